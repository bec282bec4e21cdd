//! ROS 2 messages for the MCAP log: a CDR (XCDR1, little-endian) encoder and decoder, the message
//! types imud records, and their `ros2msg` schema text exactly as rosbag2 writes it.
//!
//! The standard types (`sensor_msgs/msg/Imu`, `Temperature`, `MagneticField` and their
//! `std_msgs`, `builtin_interfaces` and `geometry_msgs` parts) match the upstream `.msg` files
//! field for field, so the recordings open in Foxglove, PlotJuggler, `ros2 bag`, Python
//! `mcap-ros2-support` and `rosbags`. The `imud_msgs` types mirror imu-bus's own sample types.
//!
//! Wire format: a 4-byte encapsulation header `00 01 00 00` (CDR, little-endian), then the fields
//! in declaration order, each primitive aligned to its own size (8 for `float64`/`uint64`)
//! relative to the first byte after the header; strings are a `uint32` length that counts a
//! trailing NUL, the bytes and the NUL; sequences are a `uint32` count and the elements; fixed
//! arrays are the elements alone.

use crate::sample::{DaemonStatus, RawSample, raw_flags};

/// Encapsulation header of little-endian plain CDR (`CDR_LE`), the first four bytes of every
/// message.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// The line rosbag2 puts before each dependent definition in `ros2msg` schema text (80 `=`).
pub const DEFINITION_SEPARATOR: &str =
    "================================================================================";

/// Why CDR bytes could not be decoded. Offsets count from the first byte of the message
/// (the encapsulation header included).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The message does not start with the little-endian CDR encapsulation header.
    #[error("encapsulation header {found:02X?} is not little-endian CDR (00 01 00 00)")]
    BadEncapsulation {
        /// The first bytes found (up to four).
        found: Vec<u8>,
    },
    /// The message ends before a field does.
    #[error("message ends at byte {len} inside field `{field}` (needs bytes {offset}..{end})")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Where the field starts.
        offset: usize,
        /// Where it would end.
        end: usize,
        /// The message length.
        len: usize,
    },
    /// A string is not UTF-8 or lacks its terminating NUL.
    #[error("field `{field}` at byte {offset} is not a NUL-terminated UTF-8 string")]
    BadString {
        /// The field being read.
        field: &'static str,
        /// Where its length prefix starts.
        offset: usize,
    },
}

/// Appends one CDR message to a byte buffer.
pub struct CdrWriter<'a> {
    buf: &'a mut Vec<u8>,
    /// Index of the first byte after the encapsulation header (alignment origin).
    origin: usize,
}

impl<'a> CdrWriter<'a> {
    /// Starts a message at the end of `buf` by appending the encapsulation header.
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        buf.extend_from_slice(&CDR_LE_HEADER);
        let origin = buf.len();
        Self { buf, origin }
    }

    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - self.origin;
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// Writes a `uint8`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// Writes a `bool` (one byte, 0 or 1).
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    /// Writes a `uint16`.
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes an `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `uint64`.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// Writes a `string` (length including the NUL, the bytes, the NUL).
    ///
    /// A string longer than `u32::MAX - 1` bytes cannot be represented and is cut there.
    pub fn string(&mut self, s: &str) {
        let bytes = &s.as_bytes()[..s.len().min(u32::MAX as usize - 1)];
        self.u32(bytes.len() as u32 + 1);
        self.buf.extend_from_slice(bytes);
        self.buf.push(0);
    }

    /// Writes a `uint8[]` sequence (count, then the bytes). A sequence longer than `u32::MAX`
    /// bytes cannot be represented and is cut there.
    pub fn byte_sequence(&mut self, bytes: &[u8]) {
        let bytes = &bytes[..bytes.len().min(u32::MAX as usize)];
        self.u32(bytes.len() as u32);
        self.buf.extend_from_slice(bytes);
    }

    /// Writes a fixed-size `float64[N]` array (no count).
    pub fn f64_array(&mut self, values: &[f64]) {
        for &v in values {
            self.f64(v);
        }
    }

    /// Writes a fixed-size `int32[N]` array (no count).
    pub fn i32_array(&mut self, values: &[i32]) {
        for &v in values {
            self.i32(v);
        }
    }

    /// Writes a fixed-size `uint8[N]` array (no count).
    pub fn u8_array(&mut self, values: &[u8]) {
        self.buf.extend_from_slice(values);
    }
}

/// Reads one CDR message field by field. Never panics: every read is bounds-checked.
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    /// Checks the encapsulation header and positions the reader on the first field.
    pub fn new(data: &'a [u8]) -> Result<Self, CdrError> {
        // Bytes 2..4 are options, which plain CDR leaves for the writer's use; only the
        // representation identifier (bytes 0..2) decides how to decode.
        match data.get(..4) {
            Some(h) if h[..2] == CDR_LE_HEADER[..2] => Ok(Self { data, pos: 4 }),
            _ => Err(CdrError::BadEncapsulation {
                found: data[..data.len().min(4)].to_vec(),
            }),
        }
    }

    fn take(&mut self, field: &'static str, align: usize, n: usize) -> Result<&'a [u8], CdrError> {
        let rel = self.pos - 4;
        let start = self.pos + (align - rel % align) % align;
        let end = start.saturating_add(n);
        match self.data.get(start..end) {
            Some(s) => {
                self.pos = end;
                Ok(s)
            }
            None => Err(CdrError::Truncated {
                field,
                offset: start,
                end,
                len: self.data.len(),
            }),
        }
    }

    fn array<const N: usize>(
        &mut self,
        field: &'static str,
        align: usize,
    ) -> Result<[u8; N], CdrError> {
        let s = self.take(field, align, N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(s);
        Ok(out)
    }

    /// Reads a `uint8`.
    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(field, 1, 1)?[0])
    }

    /// Reads a `bool` (any non-zero byte is true).
    pub fn bool(&mut self, field: &'static str) -> Result<bool, CdrError> {
        Ok(self.u8(field)? != 0)
    }

    /// Reads a `uint16`.
    pub fn u16(&mut self, field: &'static str) -> Result<u16, CdrError> {
        Ok(u16::from_le_bytes(self.array(field, 2)?))
    }

    /// Reads an `int32`.
    pub fn i32(&mut self, field: &'static str) -> Result<i32, CdrError> {
        Ok(i32::from_le_bytes(self.array(field, 4)?))
    }

    /// Reads a `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        Ok(u32::from_le_bytes(self.array(field, 4)?))
    }

    /// Reads a `uint64`.
    pub fn u64(&mut self, field: &'static str) -> Result<u64, CdrError> {
        Ok(u64::from_le_bytes(self.array(field, 8)?))
    }

    /// Reads a `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.array(field, 8)?))
    }

    /// Reads a `string`. A zero length (written by some implementations for "") is accepted.
    pub fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let offset = self.pos;
        let n = self.u32(field)? as usize;
        let bytes = self.take(field, 1, n)?;
        let text = match bytes.split_last() {
            None => &[][..],
            Some((0, text)) => text,
            Some(_) => return Err(CdrError::BadString { field, offset }),
        };
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::BadString { field, offset })
    }

    /// Reads a `uint8[]` sequence.
    pub fn byte_sequence(&mut self, field: &'static str) -> Result<Vec<u8>, CdrError> {
        let n = self.u32(field)? as usize;
        Ok(self.take(field, 1, n)?.to_vec())
    }

    /// Reads a fixed-size `float64[N]` array.
    pub fn f64_array<const N: usize>(&mut self, field: &'static str) -> Result<[f64; N], CdrError> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// Reads a fixed-size `int32[N]` array.
    pub fn i32_array<const N: usize>(&mut self, field: &'static str) -> Result<[i32; N], CdrError> {
        let mut out = [0; N];
        for v in &mut out {
            *v = self.i32(field)?;
        }
        Ok(out)
    }

    /// Reads a fixed-size `uint8[N]` array.
    pub fn u8_array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        self.array(field, 1)
    }
}

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
# One decoded 3DM-GX1 data frame as the device sent it, with imud's timestamps.
# header.stamp: host wall clock when the frame's last byte was read.
uint32 FLAG_TEMP_STALE=1      # no temperature reading yet, or it is stale
uint32 FLAG_SATURATED=2       # at least one channel sat at a 16-bit limit
uint32 FLAG_SCALED_COUNTS=4   # counts are scaled i16 vectors, not raw ADC bits
uint32 FLAG_GAP_BEFORE=8      # frames were lost just before this one

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
uint8 command                 # reply header byte (0x01 raw bits, 0x02/0x03 vectors, ...)
uint8 reserved
uint32 flags                  # FLAG_* bits
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
uint8[5] reserved
float64 clock_offset_s        # host monotonic s at device tick 0, from the clock fit; NaN until known
float64 clock_residual_s      # RMS residual of the clock fit, s; NaN until known
uint16 gain_scale_accel       # GainScales in force
uint16 gain_scale_gyro
uint16 gain_scale_mag
uint8[2] reserved_end
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
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
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
            },
        })
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
        w.u8_array(&s.reserved);
        w.f64(s.clock_offset_s);
        w.f64(s.clock_residual_s);
        w.u16(s.gain_scale_accel);
        w.u16(s.gain_scale_gyro);
        w.u16(s.gain_scale_mag);
        w.u8_array(&s.reserved_end);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
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
                reserved: r.u8_array("reserved")?,
                clock_offset_s: r.f64("clock_offset_s")?,
                clock_residual_s: r.f64("clock_residual_s")?,
                gain_scale_accel: r.u16("gain_scale_accel")?,
                gain_scale_gyro: r.u16("gain_scale_gyro")?,
                gain_scale_mag: r.u16("gain_scale_mag")?,
                reserved_end: r.u8_array("reserved_end")?,
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
};

#[cfg(test)]
mod tests {
    use super::*;

    fn header(frame_id: &str) -> Header {
        Header {
            stamp: Time {
                sec: 1_700_000_000,
                nanosec: 123_456_789,
            },
            frame_id: frame_id.into(),
        }
    }

    fn imu() -> Imu {
        Imu {
            header: header("imu_link"),
            orientation: Quaternion::default(),
            orientation_covariance: NOT_PROVIDED_COVARIANCE,
            angular_velocity: [0.01, -0.02, 0.03].into(),
            angular_velocity_covariance: diagonal_covariance([1e-6, 2e-6, 3e-6]),
            linear_acceleration: [0.1, -0.2, -9.80665].into(),
            linear_acceleration_covariance: [0.0; 9],
        }
    }

    #[test]
    fn imu_golden_bytes() {
        let bytes = imu().to_cdr();
        // Hand-checked layout: 4 header bytes, then offsets relative to byte 4:
        // 0 sec, 4 nanosec, 8 string length (9 = "imu_link" + NUL), 12..20 text, 20 NUL,
        // 21..24 padding to 8, 24 orientation (4 x f64), 56 covariance (9 x f64), 128 angular
        // velocity, 152 covariance, 224 linear acceleration, 248 covariance, 320 end.
        assert_eq!(bytes.len(), 4 + 320);
        let mut expected_head = vec![0x00, 0x01, 0x00, 0x00];
        expected_head.extend_from_slice(&1_700_000_000i32.to_le_bytes());
        expected_head.extend_from_slice(&123_456_789u32.to_le_bytes());
        expected_head.extend_from_slice(&[9, 0, 0, 0]);
        expected_head.extend_from_slice(b"imu_link\0");
        expected_head.extend_from_slice(&[0, 0, 0]);
        assert_eq!(&bytes[..28], &expected_head[..]);
        assert_eq!(
            &bytes[4..16],
            &[
                0x00, 0xF1, 0x53, 0x65, 0x15, 0xCD, 0x5B, 0x07, 0x09, 0x00, 0x00, 0x00
            ]
        );
        let f64_at = |rel: usize| f64::from_le_bytes(bytes[4 + rel..12 + rel].try_into().unwrap());
        assert_eq!(
            [f64_at(24), f64_at(32), f64_at(40), f64_at(48)],
            [0.0, 0.0, 0.0, 1.0]
        );
        assert_eq!(f64_at(56), -1.0);
        assert_eq!(f64_at(128), 0.01);
        assert_eq!(f64_at(152), 1e-6);
        assert_eq!(f64_at(152 + 32), 2e-6);
        assert_eq!(f64_at(224 + 16), -9.80665);
        assert_eq!(f64_at(312), 0.0);
    }

    #[test]
    fn empty_frame_id_pads_to_the_next_eight() {
        let mut m = imu();
        m.header.frame_id.clear();
        let bytes = m.to_cdr();
        // 8 stamp, 4 length (1), 1 NUL, 3 padding: orientation at relative 16.
        assert_eq!(&bytes[12..20], &[1, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(bytes.len(), 4 + 16 + 296);
        assert_eq!(Imu::from_cdr(&bytes).unwrap(), m);
    }

    fn round_trip<M: RosMessage + PartialEq + std::fmt::Debug>(m: &M) {
        let bytes = m.to_cdr();
        assert_eq!(&M::from_cdr(&bytes).unwrap(), m);
        // Every strict prefix is an error, never a panic (no message here ends in padding).
        for n in 0..bytes.len() {
            assert!(
                M::from_cdr(&bytes[..n]).is_err(),
                "{} decoded from {n} bytes",
                M::DEFINITION.type_name
            );
        }
    }

    #[test]
    fn every_type_round_trips_and_rejects_truncation() {
        round_trip(&imu());
        round_trip(&Temperature {
            header: header("imu_link"),
            temperature: 24.5,
            variance: 0.0,
        });
        round_trip(&MagneticField {
            header: header("x"),
            magnetic_field: [2.2e-5, -4.2e-5, 1e-6].into(),
            magnetic_field_covariance: diagonal_covariance([1e-14, 2e-14, 3e-14]),
        });
        round_trip(&RawSampleMsg {
            header: header("imu_link"),
            sample: RawSample {
                seq: 42,
                t_device_ns: 1,
                t_host_monotonic_ns: 2,
                t_host_wall_ns: 3,
                t_sample_ns: 4,
                ticks_unwrapped: 70_000,
                accel_counts: [32768, 1, -5],
                gyro_counts: [65535, 0, 7],
                mag_counts: [-32768, 2, 3],
                temp_c: 25.25,
                ticks: 4464,
                command: 0x0C,
                reserved: 0,
                flags: raw_flags::SATURATED | raw_flags::GAP_BEFORE,
            },
        });
        round_trip(&RawFrameMsg {
            header: header("imu_link"),
            t_host_monotonic_ns: 5,
            stream_offset: 1234,
            accepted: false,
            reject_reason: "bad-checksum".into(),
            data: vec![0x0C, 1, 2, 3, 0xFF],
        });
        round_trip(&DaemonStatusMsg {
            header: header(""),
            status: DaemonStatus {
                t_host_monotonic_ns: 9,
                frames: 1,
                samples: 2,
                checksum_failures: 3,
                resyncs: 4,
                garbage_bytes: 5,
                truncated_frames: 6,
                samples_lost: 7,
                log_drops: 8,
                publish_drops: 9,
                reconnects: 10,
                calibration_id: 0xDEAD_BEEF,
                tick_period_est_s: 0.0065536,
                clock_drift_ppm: -12.5,
                temp_c: 30.0,
                device_connected: 1,
                logging: 1,
                gains_fallback: 2,
                reserved: [0, 1, 2, 3, 4],
                clock_offset_s: 1234.5,
                clock_residual_s: 2.5e-4,
                gain_scale_accel: 8500,
                gain_scale_gyro: 10_000,
                gain_scale_mag: 2000,
                reserved_end: [6, 7],
            },
        });
        round_trip(&CalibrationMsg {
            header: header("imu_link"),
            id: "abc123".into(),
            toml: "format = \"imu-model/1\"\n# µ".into(),
        });
    }

    #[test]
    fn nan_survives_the_round_trip() {
        let m = RawSampleMsg {
            sample: RawSample {
                temp_c: f64::NAN,
                ..RawSample::default()
            },
            ..RawSampleMsg::default()
        };
        let back = RawSampleMsg::from_cdr(&m.to_cdr()).unwrap();
        assert!(back.sample.temp_c.is_nan());
    }

    #[test]
    fn bad_input_is_an_error_with_its_place() {
        assert_eq!(
            Imu::from_cdr(&[0x00, 0x00, 0x00, 0x00]).unwrap_err(),
            CdrError::BadEncapsulation {
                found: vec![0, 0, 0, 0]
            }
        );
        let mut bytes = CalibrationMsg {
            header: header("f"),
            id: "id".into(),
            toml: String::new(),
        }
        .to_cdr();
        // Make the id's terminating NUL a letter.
        let nul = bytes.iter().rposition(|&b| b == b'd').unwrap() + 1;
        bytes[nul] = b'x';
        let err = CalibrationMsg::from_cdr(&bytes).unwrap_err();
        assert!(
            matches!(err, CdrError::BadString { field: "id", .. }),
            "{err}"
        );
        // A huge length never allocates or panics.
        let mut bytes = RawFrameMsg::default().to_cdr();
        let n = bytes.len();
        bytes[n - 4..].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = RawFrameMsg::from_cdr(&bytes).unwrap_err();
        assert!(
            matches!(err, CdrError::Truncated { field: "data", .. }),
            "{err}"
        );
        assert!(err.to_string().contains("`data`"), "{err}");
    }

    #[test]
    fn time_conversions() {
        let t = Time::from_ns(1_700_000_000_123_456_789);
        assert_eq!((t.sec, t.nanosec), (1_700_000_000, 123_456_789));
        assert_eq!(t.to_ns(), 1_700_000_000_123_456_789);
        assert_eq!(Time::from_ns(u64::MAX).sec, i32::MAX);
        assert_eq!(
            Time {
                sec: -1,
                nanosec: 0
            }
            .to_ns(),
            0
        );
    }

    /// Every non-primitive field type named in a schema has its own `MSG:` section, each
    /// section appears once, and separators are exactly 80 `=`.
    fn check_schema(def: &MsgDefinition) {
        const PRIMITIVES: &[&str] = &[
            "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
            "uint64", "float32", "float64", "string", "wstring",
        ];
        let text = def.schema_text();
        let sections: Vec<&str> = text.split(&format!("{DEFINITION_SEPARATOR}\n")).collect();
        let mut names = vec![def.type_name.to_string()];
        for s in &sections[1..] {
            let first = s.lines().next().unwrap();
            let name = first.strip_prefix("MSG: ").expect("MSG: line");
            assert_eq!(name.split('/').count(), 3, "{name}");
            assert!(!names.contains(&name.to_string()), "{name} twice");
            names.push(name.to_string());
        }
        for line in text.lines() {
            assert!(
                !line.starts_with('=') || line == DEFINITION_SEPARATOR,
                "bad separator {line:?}"
            );
            let line = line.split('#').next().unwrap().trim();
            if line.is_empty() || line.starts_with("MSG:") || line.starts_with('=') {
                continue;
            }
            let ty = line.split_whitespace().next().unwrap();
            let base = ty.split('[').next().unwrap();
            if PRIMITIVES.contains(&base) {
                continue;
            }
            let (pkg, name) = base.split_once('/').expect("package-qualified type");
            let full = format!("{pkg}/msg/{name}");
            assert!(
                names.contains(&full),
                "{} uses {full} without MSG section",
                def.type_name
            );
        }
    }

    #[test]
    fn schemas_are_complete_ros2msg_text() {
        for def in [
            &IMU_DEF,
            &TEMPERATURE_DEF,
            &MAGNETIC_FIELD_DEF,
            &RAW_SAMPLE_DEF,
            &RAW_FRAME_DEF,
            &DAEMON_STATUS_DEF,
            &CALIBRATION_DEF,
        ] {
            check_schema(def);
        }
        let imu = IMU_DEF.schema_text();
        assert!(imu.starts_with("# If you have no estimate"));
        assert!(imu.contains(&format!(
            "\n{DEFINITION_SEPARATOR}\nMSG: std_msgs/msg/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
        )));
        assert!(imu.contains(&format!(
            "\n{DEFINITION_SEPARATOR}\nMSG: builtin_interfaces/msg/Time\nint32 sec\nuint32 nanosec\n"
        )));
        assert_eq!(imu.matches("MSG: ").count(), 4);
        assert_eq!(DEFINITION_SEPARATOR.len(), 80);
    }
}
