//! The `.msg` definitions of every recorded type and the `ros2msg` schema text built from them,
//! exactly as rosbag2 writes it.

use super::*;

/// One `.msg` definition and the definitions it uses, for building `ros2msg` schema text.
#[derive(Debug)]
pub struct MsgDefinition {
    /// Full type name, e.g. `sensor_msgs/msg/Imu`.
    pub type_name: &'static str,
    /// The `.msg` text of this type alone.
    pub text: &'static str,
    /// Types used by the fields (directly).
    pub uses: &'static [&'static MsgDefinition],
}

impl MsgDefinition {
    /// The type's name on the DDS wire as ROS 2's middlewares register it:
    /// `sensor_msgs/msg/Imu` is `sensor_msgs::msg::dds_::Imu_`.
    pub fn dds_type_name(&self) -> String {
        let mut parts: Vec<&str> = self.type_name.split('/').collect();
        let name = parts.pop().unwrap_or_default();
        let mut out = String::with_capacity(self.type_name.len() + 12);
        for p in parts {
            out.push_str(p);
            out.push_str("::");
        }
        out.push_str("dds_::");
        out.push_str(name);
        out.push('_');
        out
    }

    /// The complete `ros2msg` schema text as rosbag2 writes it: this definition, then each
    /// dependent definition (depth first, each once) after a line of 80 `=` and a
    /// `MSG: pkg/msg/Type` line.
    pub fn schema_text(&self) -> String {
        fn collect(def: &'static MsgDefinition, out: &mut Vec<&'static MsgDefinition>) {
            for dep in def.uses {
                if !out.iter().any(|d| d.type_name == dep.type_name) {
                    out.push(dep);
                    collect(dep, out);
                }
            }
        }
        let mut deps = Vec::new();
        for dep in self.uses {
            if !deps
                .iter()
                .any(|d: &&MsgDefinition| d.type_name == dep.type_name)
            {
                deps.push(*dep);
                collect(dep, &mut deps);
            }
        }
        let mut text = self.text.to_string();
        for dep in deps {
            text.push_str(DEFINITION_SEPARATOR);
            text.push_str("\nMSG: ");
            text.push_str(dep.type_name);
            text.push('\n');
            text.push_str(dep.text);
        }
        text
    }
}

/// `builtin_interfaces/msg/Time`.
pub const TIME_DEF: MsgDefinition = MsgDefinition {
    type_name: "builtin_interfaces/msg/Time",
    text: "int32 sec\nuint32 nanosec\n",
    uses: &[],
};

/// `std_msgs/msg/Header`.
pub const HEADER_DEF: MsgDefinition = MsgDefinition {
    type_name: "std_msgs/msg/Header",
    text: "builtin_interfaces/Time stamp\nstring frame_id\n",
    uses: &[&TIME_DEF],
};

/// `geometry_msgs/msg/Quaternion` (with the upstream defaults: the identity rotation).
pub const QUATERNION_DEF: MsgDefinition = MsgDefinition {
    type_name: "geometry_msgs/msg/Quaternion",
    text: "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    uses: &[],
};

/// `geometry_msgs/msg/Vector3`.
pub const VECTOR3_DEF: MsgDefinition = MsgDefinition {
    type_name: "geometry_msgs/msg/Vector3",
    text: "float64 x\nfloat64 y\nfloat64 z\n",
    uses: &[],
};

/// `sensor_msgs/msg/Imu`.
pub const IMU_DEF: MsgDefinition = MsgDefinition {
    type_name: "sensor_msgs/msg/Imu",
    text: "\
# If you have no estimate for one of the data elements, element 0 of its covariance is -1.
# A covariance of all zeros means \"covariance unknown\".
std_msgs/Header header

geometry_msgs/Quaternion orientation
float64[9] orientation_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance # Row major x, y z
",
    uses: &[&HEADER_DEF, &QUATERNION_DEF, &VECTOR3_DEF],
};

/// `sensor_msgs/msg/Temperature`.
pub const TEMPERATURE_DEF: MsgDefinition = MsgDefinition {
    type_name: "sensor_msgs/msg/Temperature",
    text: "\
std_msgs/Header header # timestamp is the time the temperature was measured

float64 temperature # Measurement of the Temperature in Degrees Celsius.

float64 variance # 0 is interpreted as variance unknown.
",
    uses: &[&HEADER_DEF],
};

/// `sensor_msgs/msg/MagneticField`.
pub const MAGNETIC_FIELD_DEF: MsgDefinition = MsgDefinition {
    type_name: "sensor_msgs/msg/MagneticField",
    text: "\
std_msgs/Header header # timestamp is the time the field was measured

geometry_msgs/Vector3 magnetic_field # x, y, and z components of the field vector in Tesla

float64[9] magnetic_field_covariance # Row major about x, y, z axes; 0 is interpreted as unknown
",
    uses: &[&HEADER_DEF, &VECTOR3_DEF],
};

/// `imud_msgs/msg/RawSample`: every field of [`RawSample`].
pub const RAW_SAMPLE_DEF: MsgDefinition = MsgDefinition {
    type_name: "imud_msgs/msg/RawSample",
    text: "\
# One decoded data frame (3DM-GX1 reply or MIP IMU packet) as the device sent it, with imud's
# timestamps. Recordings before the device_* fields end at `flags`.
# header.stamp: host wall clock when the frame's last byte was read.
uint32 FLAG_TEMP_STALE=1      # no temperature reading yet, or it is stale
uint32 FLAG_SATURATED=2       # at least one channel sat at a 16-bit limit
uint32 FLAG_SCALED_COUNTS=4   # counts are scaled i16 vectors, not raw ADC bits
uint32 FLAG_GAP_BEFORE=8      # frames were lost just before this one
uint32 FLAG_NO_COUNTS=16      # the device sent no counts (MIP): the *_counts are zero

std_msgs/Header header
uint64 seq                    # daemon sequence number of data samples since start
uint64 t_device_ns            # unwrapped timer ticks x tick period, ns since power-on
uint64 t_host_monotonic_ns    # CLOCK_MONOTONIC when the frame's last byte was read, ns
uint64 t_host_wall_ns         # wall clock (Unix epoch) when the frame's last byte was read, ns
uint64 t_sample_ns            # sample time on the monotonic timebase (device-clock fit), ns
uint64 ticks_unwrapped        # timer ticks, +65536 per wrap
int32[3] accel_counts         # raw ADC bits as u16, or scaled i16, widened
int32[3] gyro_counts
int32[3] mag_counts
float64 temp_c                # latest device temperature, deg C (NaN before the first reading)
uint16 ticks                  # the reply's 16-bit timer ticks as sent
uint8 command                 # reply header byte (0x01 raw bits, 0x02/0x03 vectors, ...; 0x80 MIP)
uint8 reserved
uint32 flags                  # FLAG_* bits
float64[3] accel_device_m_s2  # the device's own reading before imud's calibration, m/s^2
float64[3] gyro_device_rad_s  # ... rad/s
float64[3] mag_device_gauss   # ... gauss
",
    uses: &[&HEADER_DEF],
};

/// `imud_msgs/msg/RawFrame`: one run of bytes from the device, accepted as a frame or rejected.
pub const RAW_FRAME_DEF: MsgDefinition = MsgDefinition {
    type_name: "imud_msgs/msg/RawFrame",
    text: "\
# Bytes received from the device, in stream order: a frame with a good checksum, or a run of
# rejected bytes. Together the messages are the whole byte stream.
# header.stamp: host wall clock when the bytes were read.
std_msgs/Header header
uint64 t_host_monotonic_ns    # CLOCK_MONOTONIC when the bytes were read, ns
uint64 stream_offset          # offset of data[0] in the byte stream since the port was opened
bool accepted                 # true: a frame with a good checksum
string reject_reason          # empty when accepted; else bad-checksum, malformed, truncated, garbage
uint8[] data
",
    uses: &[&HEADER_DEF],
};

/// `imud_msgs/msg/DaemonStatus`: every field of [`DaemonStatus`].
pub const DAEMON_STATUS_DEF: MsgDefinition = MsgDefinition {
    type_name: "imud_msgs/msg/DaemonStatus",
    text: "\
# Health counters of a running imud. header.stamp: host wall clock of this status.
std_msgs/Header header
uint64 t_host_monotonic_ns    # CLOCK_MONOTONIC of this status, ns
uint64 frames                 # good frames decoded since start
uint64 samples                # data samples published
uint64 checksum_failures
uint64 resyncs
uint64 garbage_bytes
uint64 truncated_frames
uint64 samples_lost           # samples the device link lost (from the device's ticks)
uint64 log_drops              # log records dropped (queue full or logging stopped)
uint64 publish_drops
uint64 reconnects
uint64 calibration_id         # content id of the calibration in force (0: uncalibrated)
float64 tick_period_est_s     # host seconds per device tick from the clock fit; NaN until known
float64 clock_drift_ppm       # device clock rate error, ppm (positive: fast); NaN until known
float64 temp_c                # NaN if none
uint8 device_connected
uint8 logging
uint8 gains_fallback          # GainScales that are configured fallbacks: 1 accel, 2 gyro, 4 mag
uint8 health_accel            # live calibration health: 0 unknown, 1 ok, 2 degraded, 3 stale, 4 uncalibrated
uint8 health_gyro
uint8 protocol                # 0 3dm-gx1, 1 mip (recordings before this field: 0)
uint8 configuration_unverified # 1: passive unit, asked nothing (recordings before this field: 0)
uint8 reserved
float64 clock_offset_s        # host monotonic s at device tick 0, from the clock fit; NaN until known
float64 clock_residual_s      # RMS residual of the clock fit, s; NaN until known
uint16 gain_scale_accel       # GainScales in force
uint16 gain_scale_gyro
uint16 gain_scale_mag
uint8[2] reserved_end
uint64 packets_unusable       # MIP data packets that were no sample (recordings before: absent)
uint64 fields_skipped         # MIP data fields skipped (unknown descriptors or sizes)
uint8 time_source             # 0 device, 1 host, 2 gnss (recordings before: absent)
uint8 time_sync               # 0 none, 1 device-fit, 2 gnss-locked, 3 gnss-holdover, 4 gnss-lost
uint8[6] reserved_sync
float64 gnss_minus_wall_s     # unit's GNSS time minus host wall clock, s; NaN until known
float64 gnss_drift_ppm        # device clock rate error against GNSS time, ppm; NaN until known
uint64 gnss_valid_transitions # times GNSS time became valid
uint64 gnss_lost_transitions  # times it was lost
",
    uses: &[&HEADER_DEF],
};

/// `imud_msgs/msg/Calibration`: a calibration put in force.
pub const CALIBRATION_DEF: MsgDefinition = MsgDefinition {
    type_name: "imud_msgs/msg/Calibration",
    text: "\
# A calibration put in force. header.stamp: host wall clock when it took effect.
std_msgs/Header header
string id                     # content id
string toml                   # the calibration file text (imu-model format)
",
    uses: &[&HEADER_DEF],
};

/// `imud_msgs/msg/CalibrationHealth`: every field of [`crate::sample::CalibrationHealth`].
pub const CALIBRATION_HEALTH_DEF: MsgDefinition = MsgDefinition {
    type_name: "imud_msgs/msg/CalibrationHealth",
    text: "\
# The daemon's calibration held against physics over one still window. header.stamp: host
# wall clock at the window's end. States: 0 unknown, 1 ok, 2 degraded, 3 stale, 4 uncalibrated.
std_msgs/Header header
uint64 t_sample_ns            # window end, samples' monotonic time base, ns
uint64 t_wall_ns              # window end, host wall clock, ns
uint64 window_start_ns        # window start, samples' monotonic time base, ns
uint64 calibration_id         # content id of the calibration held (0: none)
uint64 still_windows          # still windows tested since it was put in force
uint64 plateaus_skipped       # quiet windows that were steady rotations
float64 accel_residual_m_s2   # |mean f| - gravity
float64 accel_expected_std_m_s2
float64 accel_p               # sequential test p-value; NaN when untested
float64[3] accel_offset_m_s2  # bias shift that explains the recent windows; NaN: unobservable
float64 gyro_residual_rad_s   # |mean w| - |Earth rate|
float64 gyro_vertical_residual_rad_s  # mean w along up - Earth rate's vertical part; NaN: no latitude
float64 gyro_expected_std_rad_s
float64 gyro_p
float64[3] gyro_offset_rad_s
float64 gravity_m_s2          # the gravity held against
float64 temp_c
uint8 accel_state
uint8 gyro_state
uint8 checks                  # 1 gravity, 2 gravity learned, 4 earth rate, 8 vertical earth rate, 16 accel bias 3-D, 32 temperature outside the calibration's range
uint8 noise_source            # 0 noise tables, 1 estimated from still windows, 2 none yet
uint8 bias_tracking           # 1: the offsets are applied to the corrected stream
uint8[3] reserved
",
    uses: &[&HEADER_DEF],
};
