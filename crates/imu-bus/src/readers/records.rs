//! The byte encoding of the four published records: exactly the `#[repr(C)]` layouts of
//! [`crate::sample`] (the bytes an iceoryx2 subscriber sees in shared memory, padding zeroed),
//! written and read field by field so no `unsafe` view of a struct is needed.

use crate::sample::{CalibrationHealth, CorrectedSample, DaemonStatus, RawSample};
use crate::shm::ShmPayload;

use super::Received;

/// A record that travels on the readers' socket: its stream code and its C-layout bytes.
pub trait WireRecord: ShmPayload {
    /// The stream code in the packet header (1 raw, 2 corrected, 3 status, 4 health).
    const CODE: u8;
    /// Encoded size in bytes (`size_of::<Self>()`, checked by a test).
    const SIZE: usize;
    /// Writes the record into `out` (exactly [`Self::SIZE`] bytes).
    fn encode(&self, out: &mut [u8]);
    /// Reads a record from `bytes` (exactly [`Self::SIZE`] bytes, checked by the caller).
    fn decode(bytes: &[u8]) -> Self;
    /// The record, if `received` carries this type.
    fn take(received: Received) -> Option<Self>;
}

/// Writes little-endian fields one after the other.
struct Put<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Put<'_> {
    fn bytes(&mut self, b: &[u8]) {
        self.out[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }
    fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.bytes(&v.to_le_bytes());
    }
    fn f64s(&mut self, v: &[f64; 3]) {
        v.iter().for_each(|&x| self.f64(x));
    }
    fn i32s(&mut self, v: &[i32; 3]) {
        v.iter().for_each(|&x| self.bytes(&x.to_le_bytes()));
    }
    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }
    fn u8(&mut self, v: u8) {
        self.bytes(&[v]);
    }
}

/// Reads little-endian fields one after the other.
struct Get<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Get<'_> {
    fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0u8; N];
        a.copy_from_slice(&self.bytes[self.at..self.at + N]);
        self.at += N;
        a
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.array())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.array())
    }
    fn f64s(&mut self) -> [f64; 3] {
        [self.f64(), self.f64(), self.f64()]
    }
    fn i32s(&mut self) -> [i32; 3] {
        [(); 3].map(|()| i32::from_le_bytes(self.array()))
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.array())
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.array())
    }
    fn u8(&mut self) -> u8 {
        self.array::<1>()[0]
    }
    fn skip(&mut self, n: usize) {
        self.at += n;
    }
}

impl WireRecord for RawSample {
    const CODE: u8 = 1;
    const SIZE: usize = 176;
    fn encode(&self, out: &mut [u8]) {
        let mut p = Put { out, at: 0 };
        for v in [
            self.seq,
            self.t_device_ns,
            self.t_host_monotonic_ns,
            self.t_host_wall_ns,
            self.t_sample_ns,
            self.ticks_unwrapped,
        ] {
            p.u64(v);
        }
        p.i32s(&self.accel_counts);
        p.i32s(&self.gyro_counts);
        p.i32s(&self.mag_counts);
        // The C layout's padding before the f64 at 88, zeroed.
        p.u32(0);
        p.f64(self.temp_c);
        p.u16(self.ticks);
        p.u8(self.command);
        p.u8(self.reserved);
        p.u32(self.flags);
        p.f64s(&self.accel_device_m_s2);
        p.f64s(&self.gyro_device_rad_s);
        p.f64s(&self.mag_device_gauss);
        debug_assert_eq!(p.at, Self::SIZE);
    }
    fn decode(bytes: &[u8]) -> Self {
        let mut g = Get { bytes, at: 0 };
        let seq = g.u64();
        let t_device_ns = g.u64();
        let t_host_monotonic_ns = g.u64();
        let t_host_wall_ns = g.u64();
        let t_sample_ns = g.u64();
        let ticks_unwrapped = g.u64();
        let accel_counts = g.i32s();
        let gyro_counts = g.i32s();
        let mag_counts = g.i32s();
        g.skip(4);
        RawSample {
            seq,
            t_device_ns,
            t_host_monotonic_ns,
            t_host_wall_ns,
            t_sample_ns,
            ticks_unwrapped,
            accel_counts,
            gyro_counts,
            mag_counts,
            temp_c: g.f64(),
            ticks: g.u16(),
            command: g.u8(),
            reserved: g.u8(),
            flags: g.u32(),
            accel_device_m_s2: g.f64s(),
            gyro_device_rad_s: g.f64s(),
            mag_device_gauss: g.f64s(),
        }
    }
    fn take(received: Received) -> Option<Self> {
        match received {
            Received::Raw(r) => Some(r),
            _ => None,
        }
    }
}

impl WireRecord for CorrectedSample {
    const CODE: u8 = 2;
    const SIZE: usize = 128;
    fn encode(&self, out: &mut [u8]) {
        let mut p = Put { out, at: 0 };
        p.u64(self.seq);
        p.u64(self.t_sample_ns);
        p.u64(self.t_wall_ns);
        p.u64(self.t_device_ns);
        p.f64s(&self.accel_m_s2);
        p.f64s(&self.gyro_rad_s);
        p.f64s(&self.mag_gauss);
        p.f64(self.temp_c);
        p.u64(self.calibration_id);
        p.u32(self.flags);
        p.u32(self.reserved);
        debug_assert_eq!(p.at, Self::SIZE);
    }
    fn decode(bytes: &[u8]) -> Self {
        let mut g = Get { bytes, at: 0 };
        CorrectedSample {
            seq: g.u64(),
            t_sample_ns: g.u64(),
            t_wall_ns: g.u64(),
            t_device_ns: g.u64(),
            accel_m_s2: g.f64s(),
            gyro_rad_s: g.f64s(),
            mag_gauss: g.f64s(),
            temp_c: g.f64(),
            calibration_id: g.u64(),
            flags: g.u32(),
            reserved: g.u32(),
        }
    }
    fn take(received: Received) -> Option<Self> {
        match received {
            Received::Corrected(r) => Some(r),
            _ => None,
        }
    }
}

/// Bytes of a status before the time sync (`imud::DaemonStatus.v3`).
pub(super) const DAEMON_STATUS_V3_SIZE: usize = 168;

/// A v3 status (exactly [`DAEMON_STATUS_V3_SIZE`] bytes) with the time sync unknown: source
/// `device`, state `none`, NaN offset and drift, no transitions.
pub(super) fn decode_status_v3(bytes: &[u8]) -> DaemonStatus {
    let mut full = [0u8; <DaemonStatus as WireRecord>::SIZE];
    full[..DAEMON_STATUS_V3_SIZE].copy_from_slice(bytes);
    DaemonStatus {
        gnss_minus_wall_s: f64::NAN,
        gnss_drift_ppm: f64::NAN,
        ..DaemonStatus::decode(&full)
    }
}

impl WireRecord for DaemonStatus {
    const CODE: u8 = 3;
    const SIZE: usize = 208;
    fn encode(&self, out: &mut [u8]) {
        let mut p = Put { out, at: 0 };
        for v in [
            self.t_host_monotonic_ns,
            self.frames,
            self.samples,
            self.checksum_failures,
            self.resyncs,
            self.garbage_bytes,
            self.truncated_frames,
            self.samples_lost,
            self.log_drops,
            self.publish_drops,
            self.reconnects,
            self.calibration_id,
        ] {
            p.u64(v);
        }
        p.f64(self.tick_period_est_s);
        p.f64(self.clock_drift_ppm);
        p.f64(self.temp_c);
        for v in [
            self.device_connected,
            self.logging,
            self.gains_fallback,
            self.health_accel,
            self.health_gyro,
            self.protocol,
            self.configuration_unverified,
            self.reserved,
        ] {
            p.u8(v);
        }
        p.f64(self.clock_offset_s);
        p.f64(self.clock_residual_s);
        p.u16(self.gain_scale_accel);
        p.u16(self.gain_scale_gyro);
        p.u16(self.gain_scale_mag);
        p.bytes(&self.reserved_end);
        p.u64(self.packets_unusable);
        p.u64(self.fields_skipped);
        p.u8(self.time_source);
        p.u8(self.time_sync);
        p.bytes(&self.reserved_sync);
        p.f64(self.gnss_minus_wall_s);
        p.f64(self.gnss_drift_ppm);
        p.u64(self.gnss_valid_transitions);
        p.u64(self.gnss_lost_transitions);
        debug_assert_eq!(p.at, Self::SIZE);
    }
    fn decode(bytes: &[u8]) -> Self {
        let mut g = Get { bytes, at: 0 };
        DaemonStatus {
            t_host_monotonic_ns: g.u64(),
            frames: g.u64(),
            samples: g.u64(),
            checksum_failures: g.u64(),
            resyncs: g.u64(),
            garbage_bytes: g.u64(),
            truncated_frames: g.u64(),
            samples_lost: g.u64(),
            log_drops: g.u64(),
            publish_drops: g.u64(),
            reconnects: g.u64(),
            calibration_id: g.u64(),
            tick_period_est_s: g.f64(),
            clock_drift_ppm: g.f64(),
            temp_c: g.f64(),
            device_connected: g.u8(),
            logging: g.u8(),
            gains_fallback: g.u8(),
            health_accel: g.u8(),
            health_gyro: g.u8(),
            protocol: g.u8(),
            configuration_unverified: g.u8(),
            reserved: g.u8(),
            clock_offset_s: g.f64(),
            clock_residual_s: g.f64(),
            gain_scale_accel: g.u16(),
            gain_scale_gyro: g.u16(),
            gain_scale_mag: g.u16(),
            reserved_end: g.array(),
            packets_unusable: g.u64(),
            fields_skipped: g.u64(),
            time_source: g.u8(),
            time_sync: g.u8(),
            reserved_sync: g.array(),
            gnss_minus_wall_s: g.f64(),
            gnss_drift_ppm: g.f64(),
            gnss_valid_transitions: g.u64(),
            gnss_lost_transitions: g.u64(),
        }
    }
    fn take(received: Received) -> Option<Self> {
        match received {
            Received::Status(r) => Some(r),
            _ => None,
        }
    }
}

impl WireRecord for CalibrationHealth {
    const CODE: u8 = 4;
    const SIZE: usize = 176;
    fn encode(&self, out: &mut [u8]) {
        let mut p = Put { out, at: 0 };
        for v in [
            self.t_sample_ns,
            self.t_wall_ns,
            self.window_start_ns,
            self.calibration_id,
            self.still_windows,
            self.plateaus_skipped,
        ] {
            p.u64(v);
        }
        p.f64(self.accel_residual_m_s2);
        p.f64(self.accel_expected_std_m_s2);
        p.f64(self.accel_p);
        p.f64s(&self.accel_offset_m_s2);
        p.f64(self.gyro_residual_rad_s);
        p.f64(self.gyro_vertical_residual_rad_s);
        p.f64(self.gyro_expected_std_rad_s);
        p.f64(self.gyro_p);
        p.f64s(&self.gyro_offset_rad_s);
        p.f64(self.gravity_m_s2);
        p.f64(self.temp_c);
        for v in [
            self.accel_state,
            self.gyro_state,
            self.checks,
            self.noise_source,
            self.bias_tracking,
        ] {
            p.u8(v);
        }
        p.bytes(&self.reserved);
        debug_assert_eq!(p.at, Self::SIZE);
    }
    fn decode(bytes: &[u8]) -> Self {
        let mut g = Get { bytes, at: 0 };
        CalibrationHealth {
            t_sample_ns: g.u64(),
            t_wall_ns: g.u64(),
            window_start_ns: g.u64(),
            calibration_id: g.u64(),
            still_windows: g.u64(),
            plateaus_skipped: g.u64(),
            accel_residual_m_s2: g.f64(),
            accel_expected_std_m_s2: g.f64(),
            accel_p: g.f64(),
            accel_offset_m_s2: g.f64s(),
            gyro_residual_rad_s: g.f64(),
            gyro_vertical_residual_rad_s: g.f64(),
            gyro_expected_std_rad_s: g.f64(),
            gyro_p: g.f64(),
            gyro_offset_rad_s: g.f64s(),
            gravity_m_s2: g.f64(),
            temp_c: g.f64(),
            accel_state: g.u8(),
            gyro_state: g.u8(),
            checks: g.u8(),
            noise_source: g.u8(),
            bias_tracking: g.u8(),
            reserved: g.array(),
        }
    }
    fn take(received: Received) -> Option<Self> {
        match received {
            Received::Health(r) => Some(r),
            _ => None,
        }
    }
}
