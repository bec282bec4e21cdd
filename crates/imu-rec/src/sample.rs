//! The samples and health counters imud publishes, as fixed-layout types shared by the
//! shared-memory services and the MCAP recording.
//!
//! Every type is `#[repr(C)]` plain data (no pointers, no heap) so it can be placed in shared
//! memory as-is and read from other languages; field order and widths are part of the contract
//! (add fields only at the end, and bump the type name's version when a layout changes).
//!
//! # Shared-memory contract
//!
//! Each type derives iceoryx2's `ZeroCopySend` and carries a stable `type_name`, which iceoryx2
//! compares (together with size and alignment) when a process opens a service, so a subscriber
//! written in another language opens the same service by declaring the same name and layout:
//!
//! | Rust type           | iceoryx2 type name          | size | align |
//! |---------------------|-----------------------------|------|-------|
//! | [`RawSample`]       | `imud::RawSample.v2`        | 176  | 8     |
//! | [`CorrectedSample`] | `imud::CorrectedSample.v1`  | 128  | 8     |
//! | [`DaemonStatus`]    | `imud::DaemonStatus.v4`     | 208  | 8     |
//! | [`CalibrationHealth`] | `imud::CalibrationHealth.v1` | 176 | 8    |
//!
//! The user header is iceoryx2's default `()` (type name `()`, size 0, alignment 1). All
//! integers and floats are native-endian (little-endian on every supported host).
//!
//! C layout of `RawSample` (offsets in bytes):
//! ```text
//!   0 uint64_t seq;                 8 uint64_t t_device_ns;
//!  16 uint64_t t_host_monotonic_ns; 24 uint64_t t_host_wall_ns;
//!  32 uint64_t t_sample_ns;         40 uint64_t ticks_unwrapped;
//!  48 int32_t  accel_counts[3];     60 int32_t  gyro_counts[3];
//!  72 int32_t  mag_counts[3];       84 (4 bytes of padding: contents unspecified)
//!  88 double   temp_c;              96 uint16_t ticks;
//!  98 uint8_t  command;             99 uint8_t  reserved;
//! 100 uint32_t flags;             104 double   accel_device_m_s2[3];
//! 128 double   gyro_device_rad_s[3]; 152 double mag_device_gauss[3];
//! 176 = sizeof
//! ```
//! (v1, 104 bytes, ended at `flags`: v2 appends the device's own reading in SI, which is all a
//! MIP device sends.)
//! C layout of `CorrectedSample`:
//! ```text
//!   0 uint64_t seq;                 8 uint64_t t_sample_ns;
//!  16 uint64_t t_wall_ns;          24 uint64_t t_device_ns;
//!  32 double   accel_m_s2[3];      56 double   gyro_rad_s[3];
//!  80 double   mag_gauss[3];      104 double   temp_c;
//! 112 uint64_t calibration_id;    120 uint32_t flags;
//! 124 uint32_t reserved;          128 = sizeof
//! ```
//! C layout of `DaemonStatus`:
//! ```text
//!   0 uint64_t t_host_monotonic_ns;  8 uint64_t frames;
//!  16 uint64_t samples;             24 uint64_t checksum_failures;
//!  32 uint64_t resyncs;             40 uint64_t garbage_bytes;
//!  48 uint64_t truncated_frames;    56 uint64_t samples_lost;
//!  64 uint64_t log_drops;           72 uint64_t publish_drops;
//!  80 uint64_t reconnects;          88 uint64_t calibration_id;
//!  96 double   tick_period_est_s;  104 double   clock_drift_ppm;
//! 112 double   temp_c;             120 uint8_t  device_connected;
//! 121 uint8_t  logging;            122 uint8_t  gains_fallback;
//! 123 uint8_t  health_accel;       124 uint8_t  health_gyro;
//! 125 uint8_t  protocol;           126 uint8_t  configuration_unverified;
//! 127 uint8_t  reserved;
//! 128 double   clock_offset_s;
//! 136 double   clock_residual_s;   144 uint16_t gain_scale_accel;
//! 146 uint16_t gain_scale_gyro;    148 uint16_t gain_scale_mag;
//! 150 uint8_t  reserved_end[2];    152 uint64_t packets_unusable;
//! 160 uint64_t fields_skipped;     168 uint8_t  time_source;
//! 169 uint8_t  time_sync;          170 uint8_t  reserved_sync[6];
//! 176 double   gnss_minus_wall_s;  184 double   gnss_drift_ppm;
//! 192 uint64_t gnss_valid_transitions; 200 uint64_t gnss_lost_transitions;
//! 208 = sizeof
//! ```
//! (v3, 168 bytes, ended at `fields_skipped`: v4 appends the time-sync state.)
//! C layout of `CalibrationHealth`:
//! ```text
//!   0 uint64_t t_sample_ns;          8 uint64_t t_wall_ns;
//!  16 uint64_t window_start_ns;     24 uint64_t calibration_id;
//!  32 uint64_t still_windows;       40 uint64_t plateaus_skipped;
//!  48 double   accel_residual_m_s2; 56 double   accel_expected_std_m_s2;
//!  64 double   accel_p;             72 double   accel_offset_m_s2[3];
//!  96 double   gyro_residual_rad_s;104 double   gyro_vertical_residual_rad_s;
//! 112 double   gyro_expected_std_rad_s; 120 double gyro_p;
//! 128 double   gyro_offset_rad_s[3];152 double   gravity_m_s2;
//! 160 double   temp_c;             168 uint8_t  accel_state;
//! 169 uint8_t  gyro_state;         170 uint8_t  checks;
//! 171 uint8_t  noise_source;       172 uint8_t  bias_tracking;
//! 173 uint8_t  reserved[3];        176 = sizeof
//! ```
//! The sizes are checked at compile time below and every offset by a unit test, so a layout
//! change cannot slip through without a new type-name version.
//!
//! The `ZeroCopySend` derive expands to an `unsafe impl` (the derive's promise that the type is
//! `#[repr(C)]` and holds no pointers); code generated by a derive macro is not subject to the
//! workspace's `unsafe_code = "deny"`, so no `allow` is needed here.

// The marker trait and its derive only (iceoryx2's building blocks, no transport), so the
// offline tools that read these types from files link no shared-memory code.
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// iceoryx2 type name of [`RawSample`] (see the module docs for the C layout).
pub const RAW_SAMPLE_TYPE_NAME: &str = "imud::RawSample.v2";
/// iceoryx2 type name of [`CorrectedSample`] (see the module docs for the C layout).
pub const CORRECTED_SAMPLE_TYPE_NAME: &str = "imud::CorrectedSample.v1";
/// iceoryx2 type name of [`DaemonStatus`] (see the module docs for the C layout).
pub const DAEMON_STATUS_TYPE_NAME: &str = "imud::DaemonStatus.v4";
/// iceoryx2 type name of [`CalibrationHealth`] (see the module docs for the C layout).
pub const CALIBRATION_HEALTH_TYPE_NAME: &str = "imud::CalibrationHealth.v1";

// Layout guards: a size change must come with a new type-name version (and new mirrors in
// examples/python/imu_subscriber.py). Offsets are checked in the tests below.
const _: () = assert!(size_of::<RawSample>() == 176 && align_of::<RawSample>() == 8);
const _: () = assert!(size_of::<CorrectedSample>() == 128 && align_of::<CorrectedSample>() == 8);
const _: () = assert!(size_of::<DaemonStatus>() == 208 && align_of::<DaemonStatus>() == 8);
const _: () =
    assert!(size_of::<CalibrationHealth>() == 176 && align_of::<CalibrationHealth>() == 8);

/// Bit flags of a [`RawSample`].
pub mod raw_flags {
    /// No temperature reading yet (or it is older than the configured staleness limit).
    pub const TEMP_STALE: u32 = 1 << 0;
    /// At least one channel sat at a 16-bit limit.
    pub const SATURATED: u32 = 1 << 1;
    /// Counts are scaled i16 vectors (0x02/0x03/0x0C/0x12/0x31) rather than raw ADC bits (0x01).
    pub const SCALED_COUNTS: u32 = 1 << 2;
    /// Frames were lost just before this one (the tick counter jumped further than expected).
    pub const GAP_BEFORE: u32 = 1 << 3;
    /// The device sent no counts (a MIP unit streams scaled floats): the `*_counts` fields are
    /// zero and the `*_device_*` fields are the whole reading.
    pub const NO_COUNTS: u32 = 1 << 4;
}

/// Bit flags of a [`CorrectedSample`].
pub mod corrected_flags {
    /// No calibration is loaded: values are the device's GainScale conversion only.
    pub const UNCALIBRATED: u32 = 1 << 0;
    /// The GainScales are fallbacks because the device did not answer the EEPROM read.
    pub const FALLBACK_GAINS: u32 = 1 << 1;
    /// The accel/gyro coupling of the inverse model did not converge for this sample.
    pub const NOT_CONVERGED: u32 = 1 << 2;
    /// The temperature used by temperature terms is stale or missing.
    pub const TEMP_STALE: u32 = 1 << 3;
    /// A bias offset estimated by the daemon's health monitor (`health.track-bias`) was
    /// subtracted; its value is in the latest `CalibrationHealth` and the log.
    pub const BIAS_TRACKED: u32 = 1 << 4;
}

/// One decoded data frame as the device sent it, with the daemon's timestamps.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend, serde::Serialize)]
#[repr(C)]
#[type_name("imud::RawSample.v2")]
pub struct RawSample {
    /// Daemon sequence number of data samples since start (increments by one per sample).
    pub seq: u64,
    /// Device time: unwrapped timer ticks times the tick period in force, ns since power-on
    /// (a MIP unit's reference time, or its internal timestamp's counts at 62.5 kHz).
    pub t_device_ns: u64,
    /// Host monotonic clock (CLOCK_MONOTONIC) when the frame's last byte was read, ns.
    pub t_host_monotonic_ns: u64,
    /// Host wall clock (Unix epoch) when the frame's last byte was read, ns.
    pub t_host_wall_ns: u64,
    /// Sample time on the host monotonic timebase from the online device-clock fit, ns.
    pub t_sample_ns: u64,
    /// Unwrapped timer ticks (a MIP unit's reference time in ns, or its internal timestamp).
    pub ticks_unwrapped: u64,
    /// Accelerometer counts (raw ADC bits as u16, or scaled i16, widened; zero with
    /// [`raw_flags::NO_COUNTS`]).
    pub accel_counts: [i32; 3],
    /// Gyro counts.
    pub gyro_counts: [i32; 3],
    /// Magnetometer counts.
    pub mag_counts: [i32; 3],
    /// Latest device temperature, deg C (NaN before the first reading).
    pub temp_c: f64,
    /// The reply's 16-bit timer ticks as sent (a MIP unit's: the low 16 bits).
    pub ticks: u16,
    /// Reply header byte (0x01 raw bits, 0x02/0x03 vectors, ...; 0x80, the data set, for MIP).
    pub command: u8,
    /// Reserved, zero.
    pub reserved: u8,
    /// [`raw_flags`] bits.
    pub flags: u32,
    /// The device's own reading of specific force before imud's calibration, m/s^2: the
    /// GainScale conversion of the counts (3DM-GX1), the scaled field (MIP).
    pub accel_device_m_s2: [f64; 3],
    /// The device's own reading of angular rate, rad/s (as [`Self::accel_device_m_s2`]).
    pub gyro_device_rad_s: [f64; 3],
    /// The device's own reading of the magnetic field, gauss (as [`Self::accel_device_m_s2`]).
    pub mag_device_gauss: [f64; 3],
}

/// One sample in SI units with the calibration in force applied.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend, serde::Serialize)]
#[repr(C)]
#[type_name("imud::CorrectedSample.v1")]
pub struct CorrectedSample {
    /// Same as the [`RawSample::seq`] it was computed from.
    pub seq: u64,
    /// Sample time on the host monotonic timebase, ns.
    pub t_sample_ns: u64,
    /// Sample time on the wall clock (Unix epoch), ns.
    pub t_wall_ns: u64,
    /// Device time, ns since power-on.
    pub t_device_ns: u64,
    /// Specific force, sensor frame, m/s^2.
    pub accel_m_s2: [f64; 3],
    /// Angular rate, sensor frame, rad/s.
    pub gyro_rad_s: [f64; 3],
    /// Magnetic field, sensor frame, gauss.
    pub mag_gauss: [f64; 3],
    /// Device temperature, deg C (NaN if unknown).
    pub temp_c: f64,
    /// Content id of the calibration in force (0 when uncalibrated).
    pub calibration_id: u64,
    /// [`corrected_flags`] bits.
    pub flags: u32,
    /// Reserved, zero.
    pub reserved: u32,
}

/// Health counters of a running daemon (published about once a second and on change).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend, serde::Serialize)]
#[repr(C)]
#[type_name("imud::DaemonStatus.v4")]
pub struct DaemonStatus {
    /// Host monotonic time of this status, ns.
    pub t_host_monotonic_ns: u64,
    /// Good frames decoded since start.
    pub frames: u64,
    /// Data samples published.
    pub samples: u64,
    /// Candidate frames whose checksum failed.
    pub checksum_failures: u64,
    /// Times the decoder regained sync after losing it.
    pub resyncs: u64,
    /// Bytes skipped as garbage.
    pub garbage_bytes: u64,
    /// Frames cut short.
    pub truncated_frames: u64,
    /// Samples lost on the device link (tick gaps).
    pub samples_lost: u64,
    /// Log records dropped because the writer queue was full or logging was stopped.
    pub log_drops: u64,
    /// Samples the shared-memory publishers could not publish (a failed loan or send, see
    /// `imu_bus::shm::Publishers::drops`), plus packets imud's readers' socket could not queue
    /// for a slow reader (`imu_bus::readers`); samples a slow subscriber lost to overwriting are
    /// not counted.
    pub publish_drops: u64,
    /// Device reconnects after a loss.
    pub reconnects: u64,
    /// Content id of the calibration in force (0 when uncalibrated).
    pub calibration_id: u64,
    /// Host seconds per device tick from the device-clock fit, s (NaN until known).
    pub tick_period_est_s: f64,
    /// Device clock rate error against the host clock, ppm; positive: the device runs fast
    /// (NaN until known).
    pub clock_drift_ppm: f64,
    /// Latest temperature, deg C (NaN if none).
    pub temp_c: f64,
    /// 1 while the device is connected and streaming.
    pub device_connected: u8,
    /// 1 while MCAP logging is active.
    pub logging: u8,
    /// Which GainScales in force are the configured fallbacks (the device's EEPROM read
    /// failed): bit 0 accel, bit 1 gyro, bit 2 mag.
    pub gains_fallback: u8,
    /// The live calibration health of the accelerometers ([`health_state`]; `unknown` when the
    /// health monitor is off). Bytes that were reserved (zero) before: the layout is unchanged.
    pub health_accel: u8,
    /// The live calibration health of the gyros ([`health_state`]).
    pub health_gyro: u8,
    /// The protocol the device speaks ([`device_protocol`]; a byte reserved in v2).
    pub protocol: u8,
    /// 1 when the device's configuration was not verified: a passive unit
    /// (`device.configure = false`), asked nothing, its stream taken as it is (its rate and
    /// clock learned from the data, its scale words the configured ones). 0 when start-up
    /// set up and read back the unit (and in every status before this field: a reserved
    /// byte, zero, so the layout and type name are unchanged).
    pub configuration_unverified: u8,
    /// Reserved, zero.
    pub reserved: u8,
    /// Host monotonic time, s, at which the device's unwrapped tick count was 0, from the clock
    /// fit (a sample's time is `clock_offset_s + ticks * tick_period_est_s` plus the link's least
    /// latency; NaN until known).
    pub clock_offset_s: f64,
    /// RMS residual of the clock fit (its lower-envelope points about the line), s (NaN until
    /// known).
    pub clock_residual_s: f64,
    /// Accelerometer GainScale in force.
    pub gain_scale_accel: u16,
    /// Gyro GainScale in force.
    pub gain_scale_gyro: u16,
    /// Magnetometer GainScale in force.
    pub gain_scale_mag: u16,
    /// Reserved, zero.
    pub reserved_end: [u8; 2],
    /// MIP data packets that were no sample: undecodable, or without the configured clock,
    /// accel or gyro field (0 for a 3DM-GX1).
    pub packets_unusable: u64,
    /// MIP data fields skipped: unknown descriptors, or known ones of an unexpected size.
    pub fields_skipped: u64,
    /// Where the sample stamps come from ([`time_source`], `device.time-source`).
    pub time_source: u8,
    /// How the stamps stand against their source ([`time_sync`]).
    pub time_sync: u8,
    /// Reserved, zero.
    pub reserved_sync: [u8; 6],
    /// The unit's GNSS time minus the host wall clock, s, from the GNSS fit (NaN until the unit
    /// reported valid GNSS time with `time-source = "gnss"`; held through an outage).
    pub gnss_minus_wall_s: f64,
    /// The device clock's rate error against GNSS time, ppm; positive: the device runs fast
    /// (NaN until fitted).
    pub gnss_drift_ppm: f64,
    /// Times the unit's GNSS time became valid.
    pub gnss_valid_transitions: u64,
    /// Times it was lost (went invalid or absent, or the device session that had it ended).
    pub gnss_lost_transitions: u64,
}

/// [`DaemonStatus::time_source`] codes (`device.time-source`).
pub mod time_source {
    /// The device clock mapped onto the host clock by the clock fit (and every status before
    /// this field).
    pub const DEVICE: u8 = 0;
    /// The host's receive time of each frame, as is.
    pub const HOST: u8 = 1;
    /// The unit's GNSS time (UTC) for the wall stamps, the device clock fit for the monotonic.
    pub const GNSS: u8 = 2;

    /// The source's name as configured (`invalid` for a byte that is no source).
    pub fn name(code: u8) -> &'static str {
        match code {
            DEVICE => "device",
            HOST => "host",
            GNSS => "gnss",
            _ => "invalid",
        }
    }
}

/// [`DaemonStatus::time_sync`] codes.
pub mod time_sync {
    /// Nothing to synchronise to yet (host stamps; the device fit or GNSS time not there yet).
    pub const NONE: u8 = 0;
    /// Stamps follow the fit of the device clock to the host clock.
    pub const DEVICE_FIT: u8 = 1;
    /// Wall stamps follow the unit's valid GNSS time.
    pub const GNSS_LOCKED: u8 = 2;
    /// GNSS time is invalid or absent: wall stamps hold over on the device clock.
    pub const GNSS_HOLDOVER: u8 = 3;
    /// Held over too long, or the device session that had GNSS time ended.
    pub const GNSS_LOST: u8 = 4;

    /// The state's name as imu-echo prints it (`invalid` for a byte that is no state).
    pub fn name(code: u8) -> &'static str {
        match code {
            NONE => "none",
            DEVICE_FIT => "device-fit",
            GNSS_LOCKED => "gnss-locked",
            GNSS_HOLDOVER => "gnss-holdover",
            GNSS_LOST => "gnss-lost",
            _ => "invalid",
        }
    }
}

/// [`DaemonStatus::protocol`] codes.
pub mod device_protocol {
    /// The 3DM-GX1 (and every v2 status, where the byte was reserved).
    pub const GX1: u8 = 0;
    /// A MIP unit.
    pub const MIP: u8 = 1;
    /// A ROS 2 `sensor_msgs/msg/Imu` topic taken over DDS as the device (`imud --ros2-input`).
    pub const ROS2_INPUT: u8 = 2;
    /// An Xsens MTi.
    pub const XSENS: u8 = 3;
    /// A VectorNav VN-100/200/300.
    pub const VECTORNAV: u8 = 4;
}

/// The health of one triad's calibration ([`CalibrationHealth`] `accel_state` / `gyro_state`).
pub mod health_state {
    use super::HealthState;

    /// No still window has been tested yet.
    pub const UNKNOWN: u8 = HealthState::Unknown as u8;
    /// The still windows agree with gravity and Earth's rate within the noise model.
    pub const OK: u8 = HealthState::Ok as u8;
    /// The latest still windows disagree beyond the false-alarm bound: something moved.
    pub const DEGRADED: u8 = HealthState::Degraded as u8;
    /// They disagree persistently and grossly: recalibrate.
    pub const STALE: u8 = HealthState::Stale as u8;
    /// No calibration is loaded: there is nothing to hold against physics.
    pub const UNCALIBRATED: u8 = HealthState::Uncalibrated as u8;

    /// The name of a state byte as the daemon logs it and imu-echo prints it (`invalid` for a
    /// byte that is no state).
    pub fn name(state: u8) -> &'static str {
        HealthState::from_code(state).map_or("invalid", HealthState::name)
    }
}

/// The health of one triad's calibration; on the bus as its `u8` code ([`health_state`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum HealthState {
    /// No still window has been tested yet.
    #[default]
    Unknown = 0,
    /// The still windows agree with gravity and Earth's rate within the noise model.
    Ok = 1,
    /// The latest still windows disagree beyond the false-alarm bound: something moved.
    Degraded = 2,
    /// They disagree persistently and grossly: recalibrate.
    Stale = 3,
    /// No calibration is loaded: there is nothing to hold against physics.
    Uncalibrated = 4,
}

impl HealthState {
    /// The state's byte in [`CalibrationHealth`] and [`DaemonStatus`].
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The state of a byte, `None` for a byte that is no state.
    pub fn from_code(code: u8) -> Option<HealthState> {
        [
            HealthState::Unknown,
            HealthState::Ok,
            HealthState::Degraded,
            HealthState::Stale,
            HealthState::Uncalibrated,
        ]
        .into_iter()
        .find(|s| s.code() == code)
    }

    /// The state's name as the daemon logs it and imu-echo prints it.
    pub fn name(self) -> &'static str {
        match self {
            HealthState::Unknown => "unknown",
            HealthState::Ok => "ok",
            HealthState::Degraded => "degraded",
            HealthState::Stale => "stale",
            HealthState::Uncalibrated => "uncalibrated",
        }
    }
}

/// Which checks a [`CalibrationHealth`] could make (bit flags of `checks`).
pub mod health_checks {
    /// |f| against a known gravity (configured value or normal gravity at a latitude).
    pub const GRAVITY: u8 = 1 << 0;
    /// |f| against the gravity learned from the first still windows: changes only.
    pub const GRAVITY_LEARNED: u8 = 1 << 1;
    /// The rate against Earth's rate (its magnitude; the heading is unknown).
    pub const EARTH_RATE: u8 = 1 << 2;
    /// The vertical component of Earth's rate (a latitude is configured).
    pub const EARTH_RATE_VERTICAL: u8 = 1 << 3;
    /// Still windows in several orientations: the accel bias offset is estimated in 3-D (with
    /// one orientation only its component along gravity is seen).
    pub const ACCEL_BIAS_3D: u8 = 1 << 4;
    /// The window's temperature lies outside the range the calibration's data covered
    /// (`provenance.temperature-range-c`): a thermal effect the calibration never saw may be
    /// why it disagrees.
    pub const TEMP_OUT_OF_RANGE: u8 = 1 << 5;
}

/// Where the expected scatter of a [`CalibrationHealth`] comes from (`noise_source`).
pub mod health_noise_source {
    /// The calibration's noise tables (white, bias instability, random walk).
    pub const TABLES: u8 = 0;
    /// Estimated from the scatter within the first still windows (white noise only).
    pub const ESTIMATED: u8 = 1;
    /// Not known yet (still estimating): no test was made.
    pub const NONE: u8 = 2;
}

/// The daemon's verdict on its calibration from one still window: the corrected specific force
/// against gravity and the corrected rate against Earth's rate, with the scatter the
/// calibration's noise model allows for the window's length, the sequential test's p-values,
/// the per-triad states and the bias offsets that would explain the residuals.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend, serde::Serialize)]
#[repr(C)]
#[type_name("imud::CalibrationHealth.v1")]
pub struct CalibrationHealth {
    /// End of the still window on the samples' monotonic time base, ns.
    pub t_sample_ns: u64,
    /// End of the still window on the host wall clock, ns.
    pub t_wall_ns: u64,
    /// Start of the still window on the samples' monotonic time base, ns.
    pub window_start_ns: u64,
    /// Content id of the calibration held against physics (0: none).
    pub calibration_id: u64,
    /// Still windows tested since the calibration was put in force.
    pub still_windows: u64,
    /// Quiet windows that were steady rotations (rate plateaus), not still, and were skipped.
    pub plateaus_skipped: u64,
    /// |mean corrected specific force| - gravity over the window, m/s^2.
    pub accel_residual_m_s2: f64,
    /// Its expected standard deviation (noise model at this window length), m/s^2.
    pub accel_expected_std_m_s2: f64,
    /// p-value of the accel sequential test (NaN when untested).
    pub accel_p: f64,
    /// Accel bias shift that would explain the recent windows, m/s^2 (NaN where unobservable).
    pub accel_offset_m_s2: [f64; 3],
    /// |mean corrected rate| - |Earth rate|, rad/s.
    pub gyro_residual_rad_s: f64,
    /// Mean corrected rate along up minus Earth rate's vertical part, rad/s (NaN without a
    /// configured latitude).
    pub gyro_vertical_residual_rad_s: f64,
    /// Expected standard deviation per axis of the window's mean rate (noise and unknown
    /// heading), rad/s.
    pub gyro_expected_std_rad_s: f64,
    /// p-value of the gyro sequential test (NaN when untested).
    pub gyro_p: f64,
    /// Gyro bias shift that would explain the recent windows, rad/s.
    pub gyro_offset_rad_s: [f64; 3],
    /// The gravity the specific force is held against, m/s^2.
    pub gravity_m_s2: f64,
    /// Mean temperature over the window, deg C (NaN if none).
    pub temp_c: f64,
    /// Accel state ([`health_state`]).
    pub accel_state: u8,
    /// Gyro state ([`health_state`]).
    pub gyro_state: u8,
    /// Checks that were possible ([`health_checks`]).
    pub checks: u8,
    /// Where the expected scatter comes from ([`health_noise_source`]).
    pub noise_source: u8,
    /// 1 when the estimated bias offsets are being applied to the corrected stream.
    pub bias_tracking: u8,
    /// Reserved, zero.
    pub reserved: [u8; 3],
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::offset_of;

    #[test]
    fn raw_sample_layout_matches_the_documented_c_layout() {
        assert_eq!(offset_of!(RawSample, seq), 0);
        assert_eq!(offset_of!(RawSample, t_device_ns), 8);
        assert_eq!(offset_of!(RawSample, t_host_monotonic_ns), 16);
        assert_eq!(offset_of!(RawSample, t_host_wall_ns), 24);
        assert_eq!(offset_of!(RawSample, t_sample_ns), 32);
        assert_eq!(offset_of!(RawSample, ticks_unwrapped), 40);
        assert_eq!(offset_of!(RawSample, accel_counts), 48);
        assert_eq!(offset_of!(RawSample, gyro_counts), 60);
        assert_eq!(offset_of!(RawSample, mag_counts), 72);
        assert_eq!(offset_of!(RawSample, temp_c), 88);
        assert_eq!(offset_of!(RawSample, ticks), 96);
        assert_eq!(offset_of!(RawSample, command), 98);
        assert_eq!(offset_of!(RawSample, reserved), 99);
        assert_eq!(offset_of!(RawSample, flags), 100);
        assert_eq!(offset_of!(RawSample, accel_device_m_s2), 104);
        assert_eq!(offset_of!(RawSample, gyro_device_rad_s), 128);
        assert_eq!(offset_of!(RawSample, mag_device_gauss), 152);
        assert_eq!(size_of::<RawSample>(), 176);
    }

    #[test]
    fn corrected_sample_layout_matches_the_documented_c_layout() {
        assert_eq!(offset_of!(CorrectedSample, seq), 0);
        assert_eq!(offset_of!(CorrectedSample, t_sample_ns), 8);
        assert_eq!(offset_of!(CorrectedSample, t_wall_ns), 16);
        assert_eq!(offset_of!(CorrectedSample, t_device_ns), 24);
        assert_eq!(offset_of!(CorrectedSample, accel_m_s2), 32);
        assert_eq!(offset_of!(CorrectedSample, gyro_rad_s), 56);
        assert_eq!(offset_of!(CorrectedSample, mag_gauss), 80);
        assert_eq!(offset_of!(CorrectedSample, temp_c), 104);
        assert_eq!(offset_of!(CorrectedSample, calibration_id), 112);
        assert_eq!(offset_of!(CorrectedSample, flags), 120);
        assert_eq!(offset_of!(CorrectedSample, reserved), 124);
        assert_eq!(size_of::<CorrectedSample>(), 128);
    }

    #[test]
    fn daemon_status_layout_matches_the_documented_c_layout() {
        assert_eq!(offset_of!(DaemonStatus, t_host_monotonic_ns), 0);
        assert_eq!(offset_of!(DaemonStatus, frames), 8);
        assert_eq!(offset_of!(DaemonStatus, samples), 16);
        assert_eq!(offset_of!(DaemonStatus, checksum_failures), 24);
        assert_eq!(offset_of!(DaemonStatus, resyncs), 32);
        assert_eq!(offset_of!(DaemonStatus, garbage_bytes), 40);
        assert_eq!(offset_of!(DaemonStatus, truncated_frames), 48);
        assert_eq!(offset_of!(DaemonStatus, samples_lost), 56);
        assert_eq!(offset_of!(DaemonStatus, log_drops), 64);
        assert_eq!(offset_of!(DaemonStatus, publish_drops), 72);
        assert_eq!(offset_of!(DaemonStatus, reconnects), 80);
        assert_eq!(offset_of!(DaemonStatus, calibration_id), 88);
        assert_eq!(offset_of!(DaemonStatus, tick_period_est_s), 96);
        assert_eq!(offset_of!(DaemonStatus, clock_drift_ppm), 104);
        assert_eq!(offset_of!(DaemonStatus, temp_c), 112);
        assert_eq!(offset_of!(DaemonStatus, device_connected), 120);
        assert_eq!(offset_of!(DaemonStatus, logging), 121);
        assert_eq!(offset_of!(DaemonStatus, gains_fallback), 122);
        assert_eq!(offset_of!(DaemonStatus, health_accel), 123);
        assert_eq!(offset_of!(DaemonStatus, health_gyro), 124);
        assert_eq!(offset_of!(DaemonStatus, protocol), 125);
        assert_eq!(offset_of!(DaemonStatus, configuration_unverified), 126);
        assert_eq!(offset_of!(DaemonStatus, reserved), 127);
        assert_eq!(offset_of!(DaemonStatus, clock_offset_s), 128);
        assert_eq!(offset_of!(DaemonStatus, clock_residual_s), 136);
        assert_eq!(offset_of!(DaemonStatus, gain_scale_accel), 144);
        assert_eq!(offset_of!(DaemonStatus, gain_scale_gyro), 146);
        assert_eq!(offset_of!(DaemonStatus, gain_scale_mag), 148);
        assert_eq!(offset_of!(DaemonStatus, reserved_end), 150);
        assert_eq!(offset_of!(DaemonStatus, packets_unusable), 152);
        assert_eq!(offset_of!(DaemonStatus, fields_skipped), 160);
        assert_eq!(offset_of!(DaemonStatus, time_source), 168);
        assert_eq!(offset_of!(DaemonStatus, time_sync), 169);
        assert_eq!(offset_of!(DaemonStatus, reserved_sync), 170);
        assert_eq!(offset_of!(DaemonStatus, gnss_minus_wall_s), 176);
        assert_eq!(offset_of!(DaemonStatus, gnss_drift_ppm), 184);
        assert_eq!(offset_of!(DaemonStatus, gnss_valid_transitions), 192);
        assert_eq!(offset_of!(DaemonStatus, gnss_lost_transitions), 200);
        assert_eq!(size_of::<DaemonStatus>(), 208);
    }

    #[test]
    fn calibration_health_layout_matches_the_documented_c_layout() {
        assert_eq!(offset_of!(CalibrationHealth, t_sample_ns), 0);
        assert_eq!(offset_of!(CalibrationHealth, window_start_ns), 16);
        assert_eq!(offset_of!(CalibrationHealth, still_windows), 32);
        assert_eq!(offset_of!(CalibrationHealth, accel_residual_m_s2), 48);
        assert_eq!(offset_of!(CalibrationHealth, accel_offset_m_s2), 72);
        assert_eq!(offset_of!(CalibrationHealth, gyro_residual_rad_s), 96);
        assert_eq!(offset_of!(CalibrationHealth, gyro_expected_std_rad_s), 112);
        assert_eq!(offset_of!(CalibrationHealth, gyro_offset_rad_s), 128);
        assert_eq!(offset_of!(CalibrationHealth, gravity_m_s2), 152);
        assert_eq!(offset_of!(CalibrationHealth, temp_c), 160);
        assert_eq!(offset_of!(CalibrationHealth, accel_state), 168);
        assert_eq!(offset_of!(CalibrationHealth, reserved), 173);
        assert_eq!(size_of::<CalibrationHealth>(), 176);
    }
}
