//! The message types imud records (the standard `sensor_msgs` types and `imud_msgs`), each with
//! its CDR encoding and definition.

use super::*;

/// A ROS 2 message type with its CDR encoding and schema.
pub trait RosMessage: Sized {
    /// The type's definition (its name and `.msg` text).
    const DEFINITION: &'static MsgDefinition;

    /// Appends the fields (no encapsulation header).
    fn write_fields(&self, w: &mut CdrWriter<'_>);

    /// Reads the fields (after the encapsulation header).
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError>;

    /// Appends a whole CDR message (header and fields) to `buf`.
    fn encode_into(&self, buf: &mut Vec<u8>) {
        let mut w = CdrWriter::new(buf);
        self.write_fields(&mut w);
    }

    /// The whole CDR message.
    fn to_cdr(&self) -> Vec<u8> {
        let mut buf = Vec::with_capacity(64);
        self.encode_into(&mut buf);
        buf
    }

    /// Decodes a whole CDR message (trailing bytes are ignored).
    fn from_cdr(data: &[u8]) -> Result<Self, CdrError> {
        let mut r = CdrReader::new(data)?;
        Self::read_fields(&mut r)
    }
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the Unix epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds, `0..1_000_000_000`.
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds since the epoch (saturating at `i32::MAX` seconds, in 2038).
    pub fn from_ns(t_ns: u64) -> Self {
        let sec = t_ns / 1_000_000_000;
        match i32::try_from(sec) {
            Ok(sec) => Self {
                sec,
                nanosec: (t_ns % 1_000_000_000) as u32,
            },
            Err(_) => Self {
                sec: i32::MAX,
                nanosec: 999_999_999,
            },
        }
    }

    /// To nanoseconds since the epoch (times before it give 0).
    pub fn to_ns(self) -> u64 {
        let ns = i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec);
        u64::try_from(ns).unwrap_or(0)
    }
}

impl RosMessage for Time {
    const DEFINITION: &'static MsgDefinition = &TIME_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            sec: r.i32("stamp.sec")?,
            nanosec: r.u32("stamp.nanosec")?,
        })
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Header {
    /// Time of the data.
    pub stamp: Time,
    /// Coordinate frame of the data.
    pub frame_id: String,
}

impl RosMessage for Header {
    const DEFINITION: &'static MsgDefinition = &HEADER_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.stamp.write_fields(w);
        w.string(&self.frame_id);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            stamp: Time::read_fields(r)?,
            frame_id: r.string("header.frame_id")?,
        })
    }
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w (scalar part).
    pub w: f64,
}

impl Default for Quaternion {
    /// The identity rotation, as the upstream definition's defaults.
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl RosMessage for Quaternion {
    const DEFINITION: &'static MsgDefinition = &QUATERNION_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        w.f64_array(&[self.x, self.y, self.z, self.w]);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let [x, y, z, w] = r.f64_array::<4>("quaternion")?;
        Ok(Self { x, y, z, w })
    }
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl From<[f64; 3]> for Vector3 {
    fn from([x, y, z]: [f64; 3]) -> Self {
        Self { x, y, z }
    }
}

impl From<Vector3> for [f64; 3] {
    fn from(v: Vector3) -> Self {
        [v.x, v.y, v.z]
    }
}

impl RosMessage for Vector3 {
    const DEFINITION: &'static MsgDefinition = &VECTOR3_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        w.f64_array(&[self.x, self.y, self.z]);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(r.f64_array::<3>("vector3")?.into())
    }
}

/// A 3x3 row-major covariance with the given variances on the diagonal.
pub fn diagonal_covariance(variances: [f64; 3]) -> [f64; 9] {
    let mut c = [0.0; 9];
    c[0] = variances[0];
    c[4] = variances[1];
    c[8] = variances[2];
    c
}

/// The covariance that says "no estimate of this element" (REP-145, sensor_msgs/Imu): element 0
/// is -1.
pub const NOT_PROVIDED_COVARIANCE: [f64; 9] = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

/// `sensor_msgs/msg/Imu`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Imu {
    /// Sample time and sensor frame.
    pub header: Header,
    /// Orientation (identity with [`NOT_PROVIDED_COVARIANCE`] when not estimated).
    pub orientation: Quaternion,
    /// Row-major covariance of the orientation, rad^2.
    pub orientation_covariance: [f64; 9],
    /// Angular rate, rad/s.
    pub angular_velocity: Vector3,
    /// Row-major covariance, (rad/s)^2; all zeros: unknown.
    pub angular_velocity_covariance: [f64; 9],
    /// Specific force, m/s^2.
    pub linear_acceleration: Vector3,
    /// Row-major covariance, (m/s^2)^2; all zeros: unknown.
    pub linear_acceleration_covariance: [f64; 9],
}

impl RosMessage for Imu {
    const DEFINITION: &'static MsgDefinition = &IMU_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.header.write_fields(w);
        self.orientation.write_fields(w);
        w.f64_array(&self.orientation_covariance);
        self.angular_velocity.write_fields(w);
        w.f64_array(&self.angular_velocity_covariance);
        self.linear_acceleration.write_fields(w);
        w.f64_array(&self.linear_acceleration_covariance);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            orientation: Quaternion::read_fields(r)?,
            orientation_covariance: r.f64_array("orientation_covariance")?,
            angular_velocity: Vector3::read_fields(r)?,
            angular_velocity_covariance: r.f64_array("angular_velocity_covariance")?,
            linear_acceleration: Vector3::read_fields(r)?,
            linear_acceleration_covariance: r.f64_array("linear_acceleration_covariance")?,
        })
    }
}

/// `sensor_msgs/msg/Temperature`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Temperature {
    /// Measurement time and frame.
    pub header: Header,
    /// Temperature, deg C.
    pub temperature: f64,
    /// Variance, deg C^2; 0: unknown.
    pub variance: f64,
}

impl RosMessage for Temperature {
    const DEFINITION: &'static MsgDefinition = &TEMPERATURE_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.header.write_fields(w);
        w.f64(self.temperature);
        w.f64(self.variance);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            temperature: r.f64("temperature")?,
            variance: r.f64("variance")?,
        })
    }
}

/// `sensor_msgs/msg/MagneticField`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MagneticField {
    /// Measurement time and frame.
    pub header: Header,
    /// Field, tesla (1 gauss = 1e-4 T).
    pub magnetic_field: Vector3,
    /// Row-major covariance, T^2; all zeros: unknown.
    pub magnetic_field_covariance: [f64; 9],
}

impl RosMessage for MagneticField {
    const DEFINITION: &'static MsgDefinition = &MAGNETIC_FIELD_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.header.write_fields(w);
        self.magnetic_field.write_fields(w);
        w.f64_array(&self.magnetic_field_covariance);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            magnetic_field: Vector3::read_fields(r)?,
            magnetic_field_covariance: r.f64_array("magnetic_field_covariance")?,
        })
    }
}

/// `imud_msgs/msg/RawSample`: a [`RawSample`] with a header.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawSampleMsg {
    /// `stamp` = [`RawSample::t_host_wall_ns`].
    pub header: Header,
    /// The sample.
    pub sample: RawSample,
}

impl RosMessage for RawSampleMsg {
    const DEFINITION: &'static MsgDefinition = &RAW_SAMPLE_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        let s = &self.sample;
        self.header.write_fields(w);
        w.u64(s.seq);
        w.u64(s.t_device_ns);
        w.u64(s.t_host_monotonic_ns);
        w.u64(s.t_host_wall_ns);
        w.u64(s.t_sample_ns);
        w.u64(s.ticks_unwrapped);
        w.i32_array(&s.accel_counts);
        w.i32_array(&s.gyro_counts);
        w.i32_array(&s.mag_counts);
        w.f64(s.temp_c);
        w.u16(s.ticks);
        w.u8(s.command);
        w.u8(s.reserved);
        w.u32(s.flags);
        w.f64_array(&s.accel_device_m_s2);
        w.f64_array(&s.gyro_device_rad_s);
        w.f64_array(&s.mag_device_gauss);
    }
    /// A record of the v1 schema (before the device's own SI reading) reads with NaN there.
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let mut msg = Self {
            header: Header::read_fields(r)?,
            sample: RawSample {
                seq: r.u64("seq")?,
                t_device_ns: r.u64("t_device_ns")?,
                t_host_monotonic_ns: r.u64("t_host_monotonic_ns")?,
                t_host_wall_ns: r.u64("t_host_wall_ns")?,
                t_sample_ns: r.u64("t_sample_ns")?,
                ticks_unwrapped: r.u64("ticks_unwrapped")?,
                accel_counts: r.i32_array("accel_counts")?,
                gyro_counts: r.i32_array("gyro_counts")?,
                mag_counts: r.i32_array("mag_counts")?,
                temp_c: r.f64("temp_c")?,
                ticks: r.u16("ticks")?,
                command: r.u8("command")?,
                reserved: r.u8("reserved")?,
                flags: r.u32("flags")?,
                accel_device_m_s2: [f64::NAN; 3],
                gyro_device_rad_s: [f64::NAN; 3],
                mag_device_gauss: [f64::NAN; 3],
            },
        };
        // A v1 message ends at `flags` (4-aligned, so no writer pads after it).
        if r.remaining() > 0 {
            let s = &mut msg.sample;
            s.accel_device_m_s2 = r.f64_array("accel_device_m_s2")?;
            s.gyro_device_rad_s = r.f64_array("gyro_device_rad_s")?;
            s.mag_device_gauss = r.f64_array("mag_device_gauss")?;
        }
        Ok(msg)
    }
}

/// `imud_msgs/msg/RawFrame`: bytes received from the device, accepted or rejected.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawFrameMsg {
    /// `stamp` = host wall clock when the bytes were read.
    pub header: Header,
    /// Host monotonic clock when the bytes were read, ns.
    pub t_host_monotonic_ns: u64,
    /// Offset of `data[0]` in the byte stream.
    pub stream_offset: u64,
    /// True for a frame with a good checksum.
    pub accepted: bool,
    /// Empty when accepted; else why the bytes were rejected.
    pub reject_reason: String,
    /// The bytes.
    pub data: Vec<u8>,
}

impl RosMessage for RawFrameMsg {
    const DEFINITION: &'static MsgDefinition = &RAW_FRAME_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.header.write_fields(w);
        w.u64(self.t_host_monotonic_ns);
        w.u64(self.stream_offset);
        w.bool(self.accepted);
        w.string(&self.reject_reason);
        w.byte_sequence(&self.data);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            t_host_monotonic_ns: r.u64("t_host_monotonic_ns")?,
            stream_offset: r.u64("stream_offset")?,
            accepted: r.bool("accepted")?,
            reject_reason: r.string("reject_reason")?,
            data: r.byte_sequence("data")?,
        })
    }
}

/// `imud_msgs/msg/DaemonStatus`: a [`DaemonStatus`] with a header.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DaemonStatusMsg {
    /// `stamp` = host wall clock of the status.
    pub header: Header,
    /// The status.
    pub status: DaemonStatus,
}

impl RosMessage for DaemonStatusMsg {
    const DEFINITION: &'static MsgDefinition = &DAEMON_STATUS_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        let s = &self.status;
        self.header.write_fields(w);
        for v in [
            s.t_host_monotonic_ns,
            s.frames,
            s.samples,
            s.checksum_failures,
            s.resyncs,
            s.garbage_bytes,
            s.truncated_frames,
            s.samples_lost,
            s.log_drops,
            s.publish_drops,
            s.reconnects,
            s.calibration_id,
        ] {
            w.u64(v);
        }
        w.f64(s.tick_period_est_s);
        w.f64(s.clock_drift_ppm);
        w.f64(s.temp_c);
        w.u8(s.device_connected);
        w.u8(s.logging);
        w.u8(s.gains_fallback);
        w.u8(s.health_accel);
        w.u8(s.health_gyro);
        w.u8(s.protocol);
        w.u8(s.configuration_unverified);
        w.u8(s.reserved);
        w.f64(s.clock_offset_s);
        w.f64(s.clock_residual_s);
        w.u16(s.gain_scale_accel);
        w.u16(s.gain_scale_gyro);
        w.u16(s.gain_scale_mag);
        w.u8_array(&s.reserved_end);
        w.u64(s.packets_unusable);
        w.u64(s.fields_skipped);
        w.u8(s.time_source);
        w.u8(s.time_sync);
        w.u8_array(&s.reserved_sync);
        w.f64(s.gnss_minus_wall_s);
        w.f64(s.gnss_drift_ppm);
        w.u64(s.gnss_valid_transitions);
        w.u64(s.gnss_lost_transitions);
    }
    /// A record of the v2 schema (before the MIP counters) reads with 0 there; one of the v3
    /// schema (before the time sync) with source `device`, state `none`, NaN and 0.
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let mut msg = Self {
            header: Header::read_fields(r)?,
            status: DaemonStatus {
                t_host_monotonic_ns: r.u64("t_host_monotonic_ns")?,
                frames: r.u64("frames")?,
                samples: r.u64("samples")?,
                checksum_failures: r.u64("checksum_failures")?,
                resyncs: r.u64("resyncs")?,
                garbage_bytes: r.u64("garbage_bytes")?,
                truncated_frames: r.u64("truncated_frames")?,
                samples_lost: r.u64("samples_lost")?,
                log_drops: r.u64("log_drops")?,
                publish_drops: r.u64("publish_drops")?,
                reconnects: r.u64("reconnects")?,
                calibration_id: r.u64("calibration_id")?,
                tick_period_est_s: r.f64("tick_period_est_s")?,
                clock_drift_ppm: r.f64("clock_drift_ppm")?,
                temp_c: r.f64("temp_c")?,
                device_connected: r.u8("device_connected")?,
                logging: r.u8("logging")?,
                gains_fallback: r.u8("gains_fallback")?,
                health_accel: r.u8("health_accel")?,
                health_gyro: r.u8("health_gyro")?,
                protocol: r.u8("protocol")?,
                configuration_unverified: r.u8("configuration_unverified")?,
                reserved: r.u8("reserved")?,
                clock_offset_s: r.f64("clock_offset_s")?,
                clock_residual_s: r.f64("clock_residual_s")?,
                gain_scale_accel: r.u16("gain_scale_accel")?,
                gain_scale_gyro: r.u16("gain_scale_gyro")?,
                gain_scale_mag: r.u16("gain_scale_mag")?,
                reserved_end: r.u8_array("reserved_end")?,
                packets_unusable: 0,
                fields_skipped: 0,
                gnss_minus_wall_s: f64::NAN,
                gnss_drift_ppm: f64::NAN,
                ..DaemonStatus::default()
            },
        };
        // A v2 message ends at `reserved_end`, a v3 one at `fields_skipped` (both 8-aligned,
        // so no writer pads after them).
        if r.remaining() > 0 {
            msg.status.packets_unusable = r.u64("packets_unusable")?;
            msg.status.fields_skipped = r.u64("fields_skipped")?;
        }
        if r.remaining() > 0 {
            let s = &mut msg.status;
            s.time_source = r.u8("time_source")?;
            s.time_sync = r.u8("time_sync")?;
            s.reserved_sync = r.u8_array("reserved_sync")?;
            s.gnss_minus_wall_s = r.f64("gnss_minus_wall_s")?;
            s.gnss_drift_ppm = r.f64("gnss_drift_ppm")?;
            s.gnss_valid_transitions = r.u64("gnss_valid_transitions")?;
            s.gnss_lost_transitions = r.u64("gnss_lost_transitions")?;
        }
        Ok(msg)
    }
}

/// `imud_msgs/msg/CalibrationHealth`: a [`CalibrationHealth`] with a header.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CalibrationHealthMsg {
    /// `stamp` = host wall clock at the window's end.
    pub header: Header,
    /// The health report.
    pub health: CalibrationHealth,
}

impl RosMessage for CalibrationHealthMsg {
    const DEFINITION: &'static MsgDefinition = &CALIBRATION_HEALTH_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        let h = &self.health;
        self.header.write_fields(w);
        for v in [
            h.t_sample_ns,
            h.t_wall_ns,
            h.window_start_ns,
            h.calibration_id,
            h.still_windows,
            h.plateaus_skipped,
        ] {
            w.u64(v);
        }
        w.f64(h.accel_residual_m_s2);
        w.f64(h.accel_expected_std_m_s2);
        w.f64(h.accel_p);
        w.f64_array(&h.accel_offset_m_s2);
        w.f64(h.gyro_residual_rad_s);
        w.f64(h.gyro_vertical_residual_rad_s);
        w.f64(h.gyro_expected_std_rad_s);
        w.f64(h.gyro_p);
        w.f64_array(&h.gyro_offset_rad_s);
        w.f64(h.gravity_m_s2);
        w.f64(h.temp_c);
        for v in [
            h.accel_state,
            h.gyro_state,
            h.checks,
            h.noise_source,
            h.bias_tracking,
        ] {
            w.u8(v);
        }
        w.u8_array(&h.reserved);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            health: CalibrationHealth {
                t_sample_ns: r.u64("t_sample_ns")?,
                t_wall_ns: r.u64("t_wall_ns")?,
                window_start_ns: r.u64("window_start_ns")?,
                calibration_id: r.u64("calibration_id")?,
                still_windows: r.u64("still_windows")?,
                plateaus_skipped: r.u64("plateaus_skipped")?,
                accel_residual_m_s2: r.f64("accel_residual_m_s2")?,
                accel_expected_std_m_s2: r.f64("accel_expected_std_m_s2")?,
                accel_p: r.f64("accel_p")?,
                accel_offset_m_s2: r.f64_array("accel_offset_m_s2")?,
                gyro_residual_rad_s: r.f64("gyro_residual_rad_s")?,
                gyro_vertical_residual_rad_s: r.f64("gyro_vertical_residual_rad_s")?,
                gyro_expected_std_rad_s: r.f64("gyro_expected_std_rad_s")?,
                gyro_p: r.f64("gyro_p")?,
                gyro_offset_rad_s: r.f64_array("gyro_offset_rad_s")?,
                gravity_m_s2: r.f64("gravity_m_s2")?,
                temp_c: r.f64("temp_c")?,
                accel_state: r.u8("accel_state")?,
                gyro_state: r.u8("gyro_state")?,
                checks: r.u8("checks")?,
                noise_source: r.u8("noise_source")?,
                bias_tracking: r.u8("bias_tracking")?,
                reserved: r.u8_array("reserved")?,
            },
        })
    }
}

/// `imud_msgs/msg/Calibration`: a calibration put in force.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CalibrationMsg {
    /// `stamp` = host wall clock when it took effect.
    pub header: Header,
    /// Content id.
    pub id: String,
    /// The calibration file text.
    pub toml: String,
}

impl RosMessage for CalibrationMsg {
    const DEFINITION: &'static MsgDefinition = &CALIBRATION_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.header.write_fields(w);
        w.string(&self.id);
        w.string(&self.toml);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            header: Header::read_fields(r)?,
            id: r.string("id")?,
            toml: r.string("toml")?,
        })
    }
}

// The flag values written into the RawSample schema must be the ones the daemon sets.
const _: () = {
    assert!(raw_flags::TEMP_STALE == 1);
    assert!(raw_flags::SATURATED == 2);
    assert!(raw_flags::SCALED_COUNTS == 4);
    assert!(raw_flags::GAP_BEFORE == 8);
    assert!(raw_flags::NO_COUNTS == 16);
};
