//! Binary output messages: sync 0xFA, a group byte, one u16 field word per group present, the
//! fields little-endian in group then bit order, and a big-endian CRC-16-CCITT.
//!
//! A message's length is computed from its field words alone (nothing else on the wire says
//! it), so every enabled bit must have a known size: [`FIELD_LEN`] holds them, and a bit whose
//! size is unknown (0 in the table, or bit 15, the extension flag of newer firmware) makes the
//! message undecodable rather than misparsed.

use smallvec::SmallVec;

use super::checksum::crc16;
use super::{SYNC, VnError};

/// Output groups, as the index into [`OutputFields::words`] (group number minus one).
pub mod group {
    /// Group 1, common outputs.
    pub const COMMON: usize = 0;
    /// Group 2, time outputs.
    pub const TIME: usize = 1;
    /// Group 3, IMU outputs.
    pub const IMU: usize = 2;
    /// Group 4, GNSS1 outputs.
    pub const GPS: usize = 3;
    /// Group 5, attitude outputs.
    pub const ATTITUDE: usize = 4;
    /// Group 6, INS outputs.
    pub const INS: usize = 5;
    /// Group 7, GNSS2 outputs.
    pub const GPS2: usize = 6;
    /// Number of output groups.
    pub const COUNT: usize = 7;
}

/// Group 1 (common) field bits.
pub mod common {
    /// Startup time, u64 ns since the unit started.
    pub const TIME_STARTUP: u16 = 1 << 0;
    /// GPS time, u64 ns since the GPS epoch (VN-200/300).
    pub const TIME_GPS: u16 = 1 << 1;
    /// Compensated angular rate, 3 f32 rad/s.
    pub const ANGULAR_RATE: u16 = 1 << 5;
    /// Compensated acceleration, 3 f32 m/s².
    pub const ACCEL: u16 = 1 << 8;
    /// Uncompensated acceleration then angular rate, 6 f32 (m/s², rad/s).
    pub const IMU: u16 = 1 << 9;
    /// Compensated magnetic field (3 f32 gauss), temperature (f32 °C), pressure (f32 kPa).
    pub const MAG_PRES: u16 = 1 << 10;
    /// Delta time (f32 s), delta theta (3 f32 deg), delta velocity (3 f32 m/s).
    pub const DELTA_THETA_VEL: u16 = 1 << 11;
}

/// Group 2 (time) field bits.
pub mod time {
    /// Startup time, u64 ns.
    pub const TIME_STARTUP: u16 = 1 << 0;
    /// GPS time, u64 ns since the GPS epoch.
    pub const TIME_GPS: u16 = 1 << 1;
    /// UTC time: i8 year since 2000, u8 month, day, hour, minute, second, u16 ms.
    pub const TIME_UTC: u16 = 1 << 6;
    /// Time status, u8 ([`TimeStatus`](super::TimeStatus)).
    pub const TIME_STATUS: u16 = 1 << 9;
}

/// Group 3 (IMU) field bits.
pub mod imu {
    /// IMU status, u16.
    pub const IMU_STATUS: u16 = 1 << 0;
    /// Uncompensated magnetic field, 3 f32 gauss.
    pub const UNCOMP_MAG: u16 = 1 << 1;
    /// Uncompensated acceleration, 3 f32 m/s².
    pub const UNCOMP_ACCEL: u16 = 1 << 2;
    /// Uncompensated angular rate, 3 f32 rad/s.
    pub const UNCOMP_GYRO: u16 = 1 << 3;
    /// Temperature, f32 °C.
    pub const TEMP: u16 = 1 << 4;
    /// Pressure, f32 kPa.
    pub const PRES: u16 = 1 << 5;
    /// Delta time (f32 s) and delta theta (3 f32 deg).
    pub const DELTA_THETA: u16 = 1 << 6;
    /// Delta velocity, 3 f32 m/s.
    pub const DELTA_VEL: u16 = 1 << 7;
    /// Compensated magnetic field, 3 f32 gauss.
    pub const MAG: u16 = 1 << 8;
    /// Compensated acceleration, 3 f32 m/s².
    pub const ACCEL: u16 = 1 << 9;
    /// Compensated angular rate, 3 f32 rad/s.
    pub const ANGULAR_RATE: u16 = 1 << 10;
}

/// Size in bytes of each field, by group and bit; 0 = unknown (the message cannot be framed).
/// From the binary group tables of VectorNav's programming library (vnproglib 1.2,
/// `Packet::BinaryGroupLengths`, as shipped in github:dawonn/vectornav), which agree with the
/// struct layouts ArduPilot's and PX4's drivers read. Bit 15 is the extension flag of newer
/// firmware, whose extra field word this codec does not read.
pub const FIELD_LEN: [[u8; 16]; group::COUNT] = [
    [8, 8, 8, 12, 16, 12, 24, 12, 12, 24, 20, 28, 2, 4, 8, 0],
    [8, 8, 8, 2, 8, 8, 8, 4, 4, 1, 0, 0, 0, 0, 0, 0],
    [2, 12, 12, 12, 4, 4, 16, 12, 12, 12, 12, 2, 40, 0, 0, 0],
    [8, 8, 2, 1, 1, 24, 24, 12, 12, 12, 4, 4, 2, 28, 0, 0],
    [2, 12, 16, 36, 12, 12, 12, 12, 12, 12, 28, 24, 12, 0, 0, 0],
    [2, 24, 24, 12, 12, 12, 12, 12, 12, 4, 4, 68, 64, 0, 0, 0],
    [8, 8, 2, 1, 1, 24, 24, 12, 12, 12, 4, 4, 2, 28, 0, 0],
];

/// The sync byte, the group byte and the CRC.
pub const MIN_OVERHEAD: usize = 4;

/// Which fields a message (or a binary output register) holds: one field word per group.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct OutputFields {
    /// Field word of each group ([`group`]); 0 = the group is absent.
    pub words: [u16; group::COUNT],
}

impl OutputFields {
    /// The group byte: bit g set when group g+1 has fields.
    pub fn groups_byte(&self) -> u8 {
        self.words
            .iter()
            .enumerate()
            .filter(|(_, w)| **w != 0)
            .fold(0, |b, (g, _)| b | 1 << g)
    }

    /// The fields of a group byte and the field words after it (`words` in group order, one per
    /// group present).
    pub fn from_header(groups: u8, words: &[u16]) -> Result<OutputFields, VnError> {
        let present = (0..group::COUNT).filter(|g| groups & 1 << g != 0).count();
        if groups == 0 || groups & 0x80 != 0 || words.len() != present || words.contains(&0) {
            return Err(VnError::BadGroups(groups));
        }
        let mut out = OutputFields::default();
        let mut next = words.iter();
        for g in 0..group::COUNT {
            if groups & 1 << g != 0 {
                out.words[g] = *next.next().unwrap_or(&0);
            }
        }
        Ok(out)
    }

    /// Bytes of the fields, or the first enabled field whose size is unknown.
    pub fn payload_len(&self) -> Result<usize, VnError> {
        let mut len = 0;
        for (g, &word) in self.words.iter().enumerate() {
            for bit in set_bits(word) {
                match FIELD_LEN[g][usize::from(bit)] {
                    0 => {
                        return Err(VnError::UnknownField {
                            group: g as u8 + 1,
                            bit,
                        });
                    }
                    n => len += usize::from(n),
                }
            }
        }
        Ok(len)
    }

    /// Sync, group byte and field words.
    pub fn header_len(&self) -> usize {
        2 + 2 * self.words.iter().filter(|w| **w != 0).count()
    }

    /// The whole message's length, CRC included.
    pub fn message_len(&self) -> Result<usize, VnError> {
        Ok(self.header_len() + self.payload_len()? + 2)
    }
}

/// The header at the start of `bytes` (sync byte first): `Ok(None)` when more bytes are needed
/// to read it, else the fields and the message length.
pub fn header(bytes: &[u8]) -> Result<Option<(OutputFields, usize)>, VnError> {
    let (Some(&sync), Some(&groups)) = (bytes.first(), bytes.get(1)) else {
        return Ok(None);
    };
    if sync != SYNC {
        return Err(VnError::BadSync(sync));
    }
    if groups == 0 || groups & 0x80 != 0 {
        return Err(VnError::BadGroups(groups));
    }
    let n = groups.count_ones() as usize;
    let Some(raw) = bytes.get(2..2 + 2 * n) else {
        return Ok(None);
    };
    // At most seven groups (bit 7 was refused above): the words fit a fixed array, so framing
    // a message allocates nothing.
    let mut words = [0u16; group::COUNT];
    for (w, c) in words.iter_mut().zip(raw.chunks_exact(2)) {
        *w = u16::from_le_bytes([c[0], c[1]]);
    }
    let fields = OutputFields::from_header(groups, &words[..n])?;
    let len = fields.message_len()?;
    Ok(Some((fields, len)))
}

/// The time status byte (group 2, bit 9).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct TimeStatus(pub u8);

impl TimeStatus {
    /// Bit 0: the GPS time of week is valid.
    pub fn time_ok(self) -> bool {
        self.0 & 1 != 0
    }
    /// Bit 1: the GPS week, hence the full GPS time, is valid.
    pub fn date_ok(self) -> bool {
        self.0 & 2 != 0
    }
    /// Bit 2: UTC time is valid.
    pub fn utc_ok(self) -> bool {
        self.0 & 4 != 0
    }
    /// The GPS time (week and time of week) is valid: what a host may stamp with.
    pub fn gps_valid(self) -> bool {
        self.time_ok() && self.date_ok()
    }
}

/// UTC time (group 2, bit 6) as the unit sends it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct TimeUtc {
    /// Years since 2000.
    pub year: i8,
    /// Month 1..=12.
    pub month: u8,
    /// Day 1..=31.
    pub day: u8,
    /// Hour.
    pub hour: u8,
    /// Minute.
    pub minute: u8,
    /// Second.
    pub second: u8,
    /// Milliseconds.
    pub ms: u16,
}

/// Delta time and delta angle over the output period (group 3, bit 6).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeltaTheta {
    /// Integration time, s.
    pub dt_s: f32,
    /// Integrated rotation, degrees.
    pub theta_deg: [f32; 3],
}

/// The values of one binary message this codec decodes; fields it does not decode (attitude,
/// INS, GNSS groups) are skipped by their size. Common-group fields land in the same values as
/// their time/IMU-group twins.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BinaryData {
    /// Nanoseconds since the unit started: its sample clock.
    pub startup_ns: Option<u64>,
    /// Nanoseconds since the GPS epoch (1980-01-06), VN-200/300.
    pub gps_ns: Option<u64>,
    /// Validity of the GPS and UTC times.
    pub time_status: Option<TimeStatus>,
    /// UTC time.
    pub time_utc: Option<TimeUtc>,
    /// IMU status word.
    pub imu_status: Option<u16>,
    /// Uncompensated magnetic field, gauss.
    pub uncomp_mag_gauss: Option<[f32; 3]>,
    /// Uncompensated acceleration, m/s².
    pub uncomp_accel_m_s2: Option<[f32; 3]>,
    /// Uncompensated angular rate, rad/s.
    pub uncomp_gyro_rad_s: Option<[f32; 3]>,
    /// Temperature, °C.
    pub temp_c: Option<f32>,
    /// Pressure, kPa.
    pub pres_kpa: Option<f32>,
    /// Delta time and delta theta.
    pub delta_theta: Option<DeltaTheta>,
    /// Delta velocity, m/s.
    pub delta_vel_m_s: Option<[f32; 3]>,
    /// Compensated magnetic field, gauss.
    pub mag_gauss: Option<[f32; 3]>,
    /// Compensated acceleration, m/s².
    pub accel_m_s2: Option<[f32; 3]>,
    /// Compensated angular rate, rad/s.
    pub angular_rate_rad_s: Option<[f32; 3]>,
}

/// Longest message held inline, sync to CRC: the calibration outputs with GPS time and the
/// time status are 103 bytes, so a longer one (a unit also sending attitude or INS fields) is
/// the only kind whose bytes go to the heap.
pub const MAX_INLINE_MESSAGE_LEN: usize = 128;

/// A good binary message: its bytes (sync to CRC), its fields and the values decoded from them.
/// The bytes are held inline up to [`MAX_INLINE_MESSAGE_LEN`], so decoding one allocates
/// nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct BinaryMessage {
    bytes: SmallVec<[u8; MAX_INLINE_MESSAGE_LEN]>,
    fields: OutputFields,
    data: BinaryData,
}

impl BinaryMessage {
    /// Checks and decodes one whole message (sync byte to CRC, nothing more).
    pub fn parse(bytes: &[u8]) -> Result<BinaryMessage, VnError> {
        let Some((fields, len)) = header(bytes)? else {
            return Err(VnError::WrongLength {
                expected: MIN_OVERHEAD,
                found: bytes.len(),
            });
        };
        if bytes.len() != len {
            return Err(VnError::WrongLength {
                expected: len,
                found: bytes.len(),
            });
        }
        let crc = crc16(&bytes[1..]);
        if crc != 0 {
            return Err(VnError::BadCrc(crc));
        }
        let data = decode_payload(&fields, &bytes[fields.header_len()..len - 2]);
        Ok(BinaryMessage {
            bytes: SmallVec::from_slice(bytes),
            fields,
            data,
        })
    }

    /// Encodes `data` as a message with `fields`: every enabled bit must be one this codec
    /// encodes and have a value in `data`.
    pub fn encode(fields: OutputFields, data: &BinaryData) -> Result<BinaryMessage, VnError> {
        let len = fields.message_len()?;
        let mut out = Vec::with_capacity(len);
        out.push(SYNC);
        out.push(fields.groups_byte());
        for &w in fields.words.iter().filter(|w| **w != 0) {
            out.extend_from_slice(&w.to_le_bytes());
        }
        for (g, &word) in fields.words.iter().enumerate() {
            for bit in 0..16u8 {
                if word & 1 << bit != 0 {
                    encode_field(g, bit, data, &mut out)?;
                }
            }
        }
        let crc = crc16(&out[1..]);
        out.extend_from_slice(&crc.to_be_bytes());
        debug_assert_eq!(out.len(), len);
        Ok(BinaryMessage {
            bytes: SmallVec::from_vec(out),
            fields,
            data: data.clone(),
        })
    }

    /// The message's bytes, sync to CRC.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Which fields it holds.
    pub fn fields(&self) -> OutputFields {
        self.fields
    }

    /// The decoded values.
    pub fn data(&self) -> &BinaryData {
        &self.data
    }
}

/// The set bits of a field word, lowest first (the order of the fields on the wire): a
/// message enables a few of sixteen, so only those are visited.
fn set_bits(word: u16) -> impl Iterator<Item = u8> {
    let mut rest = word;
    std::iter::from_fn(move || {
        (rest != 0).then(|| {
            let bit = rest.trailing_zeros() as u8;
            rest &= rest - 1;
            bit
        })
    })
}

fn f32_at(b: &[u8], i: usize) -> f32 {
    f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

fn vec3_at(b: &[u8], i: usize) -> [f32; 3] {
    [f32_at(b, i), f32_at(b, i + 4), f32_at(b, i + 8)]
}

fn u64_at(b: &[u8], i: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[i..i + 8]);
    u64::from_le_bytes(a)
}

/// Decodes the fields this codec knows from a payload whose length `fields` already matched.
fn decode_payload(fields: &OutputFields, payload: &[u8]) -> BinaryData {
    let mut d = BinaryData::default();
    let mut at = 0;
    for (g, &word) in fields.words.iter().enumerate() {
        for bit in set_bits(word) {
            let f = &payload[at..at + usize::from(FIELD_LEN[g][usize::from(bit)])];
            let flag = 1u16 << bit;
            match (g, flag) {
                (group::COMMON, common::TIME_STARTUP) | (group::TIME, time::TIME_STARTUP) => {
                    d.startup_ns = Some(u64_at(f, 0))
                }
                (group::COMMON, common::TIME_GPS) | (group::TIME, time::TIME_GPS) => {
                    d.gps_ns = Some(u64_at(f, 0))
                }
                (group::COMMON, common::ANGULAR_RATE) | (group::IMU, imu::ANGULAR_RATE) => {
                    d.angular_rate_rad_s = Some(vec3_at(f, 0))
                }
                (group::COMMON, common::ACCEL) | (group::IMU, imu::ACCEL) => {
                    d.accel_m_s2 = Some(vec3_at(f, 0))
                }
                (group::COMMON, common::IMU) => {
                    d.uncomp_accel_m_s2 = Some(vec3_at(f, 0));
                    d.uncomp_gyro_rad_s = Some(vec3_at(f, 12));
                }
                (group::COMMON, common::MAG_PRES) => {
                    d.mag_gauss = Some(vec3_at(f, 0));
                    d.temp_c = Some(f32_at(f, 12));
                    d.pres_kpa = Some(f32_at(f, 16));
                }
                (group::COMMON, common::DELTA_THETA_VEL) => {
                    d.delta_theta = Some(DeltaTheta {
                        dt_s: f32_at(f, 0),
                        theta_deg: vec3_at(f, 4),
                    });
                    d.delta_vel_m_s = Some(vec3_at(f, 16));
                }
                (group::TIME, time::TIME_UTC) => {
                    d.time_utc = Some(TimeUtc {
                        year: f[0] as i8,
                        month: f[1],
                        day: f[2],
                        hour: f[3],
                        minute: f[4],
                        second: f[5],
                        ms: u16::from_le_bytes([f[6], f[7]]),
                    })
                }
                (group::TIME, time::TIME_STATUS) => d.time_status = Some(TimeStatus(f[0])),
                (group::IMU, imu::IMU_STATUS) => {
                    d.imu_status = Some(u16::from_le_bytes([f[0], f[1]]))
                }
                (group::IMU, imu::UNCOMP_MAG) => d.uncomp_mag_gauss = Some(vec3_at(f, 0)),
                (group::IMU, imu::UNCOMP_ACCEL) => d.uncomp_accel_m_s2 = Some(vec3_at(f, 0)),
                (group::IMU, imu::UNCOMP_GYRO) => d.uncomp_gyro_rad_s = Some(vec3_at(f, 0)),
                (group::IMU, imu::TEMP) => d.temp_c = Some(f32_at(f, 0)),
                (group::IMU, imu::PRES) => d.pres_kpa = Some(f32_at(f, 0)),
                (group::IMU, imu::DELTA_THETA) => {
                    d.delta_theta = Some(DeltaTheta {
                        dt_s: f32_at(f, 0),
                        theta_deg: vec3_at(f, 4),
                    })
                }
                (group::IMU, imu::DELTA_VEL) => d.delta_vel_m_s = Some(vec3_at(f, 0)),
                (group::IMU, imu::MAG) => d.mag_gauss = Some(vec3_at(f, 0)),
                // Fields this codec does not decode are skipped by their size.
                _ => {}
            }
            at += f.len();
        }
    }
    d
}

fn put_vec3(out: &mut Vec<u8>, v: [f32; 3]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Appends one field's bytes; `MissingValue` for a field `data` has no value for (or that this
/// codec does not encode).
fn encode_field(g: usize, bit: u8, d: &BinaryData, out: &mut Vec<u8>) -> Result<(), VnError> {
    let missing = VnError::MissingValue {
        group: g as u8 + 1,
        bit,
    };
    let flag = 1u16 << bit;
    match (g, flag) {
        (group::COMMON, common::TIME_STARTUP) | (group::TIME, time::TIME_STARTUP) => {
            out.extend_from_slice(&d.startup_ns.ok_or(missing)?.to_le_bytes())
        }
        (group::COMMON, common::TIME_GPS) | (group::TIME, time::TIME_GPS) => {
            out.extend_from_slice(&d.gps_ns.ok_or(missing)?.to_le_bytes())
        }
        (group::COMMON, common::ANGULAR_RATE) | (group::IMU, imu::ANGULAR_RATE) => {
            put_vec3(out, d.angular_rate_rad_s.ok_or(missing)?)
        }
        (group::COMMON, common::ACCEL) | (group::IMU, imu::ACCEL) => {
            put_vec3(out, d.accel_m_s2.ok_or(missing)?)
        }
        (group::COMMON, common::IMU) => {
            let (a, w) = d
                .uncomp_accel_m_s2
                .zip(d.uncomp_gyro_rad_s)
                .ok_or(missing)?;
            put_vec3(out, a);
            put_vec3(out, w);
        }
        (group::COMMON, common::MAG_PRES) => {
            let m = d.mag_gauss.ok_or(missing.clone())?;
            let t = d.temp_c.ok_or(missing.clone())?;
            let p = d.pres_kpa.ok_or(missing)?;
            put_vec3(out, m);
            out.extend_from_slice(&t.to_le_bytes());
            out.extend_from_slice(&p.to_le_bytes());
        }
        (group::COMMON, common::DELTA_THETA_VEL) => {
            let t = d.delta_theta.ok_or(missing.clone())?;
            let v = d.delta_vel_m_s.ok_or(missing)?;
            out.extend_from_slice(&t.dt_s.to_le_bytes());
            put_vec3(out, t.theta_deg);
            put_vec3(out, v);
        }
        (group::TIME, time::TIME_UTC) => {
            let u = d.time_utc.ok_or(missing)?;
            out.extend_from_slice(&[u.year as u8, u.month, u.day, u.hour, u.minute, u.second]);
            out.extend_from_slice(&u.ms.to_le_bytes());
        }
        (group::TIME, time::TIME_STATUS) => out.push(d.time_status.ok_or(missing)?.0),
        (group::IMU, imu::IMU_STATUS) => {
            out.extend_from_slice(&d.imu_status.ok_or(missing)?.to_le_bytes())
        }
        (group::IMU, imu::UNCOMP_MAG) => put_vec3(out, d.uncomp_mag_gauss.ok_or(missing)?),
        (group::IMU, imu::UNCOMP_ACCEL) => put_vec3(out, d.uncomp_accel_m_s2.ok_or(missing)?),
        (group::IMU, imu::UNCOMP_GYRO) => put_vec3(out, d.uncomp_gyro_rad_s.ok_or(missing)?),
        (group::IMU, imu::TEMP) => out.extend_from_slice(&d.temp_c.ok_or(missing)?.to_le_bytes()),
        (group::IMU, imu::PRES) => out.extend_from_slice(&d.pres_kpa.ok_or(missing)?.to_le_bytes()),
        (group::IMU, imu::DELTA_THETA) => {
            let t = d.delta_theta.ok_or(missing)?;
            out.extend_from_slice(&t.dt_s.to_le_bytes());
            put_vec3(out, t.theta_deg);
        }
        (group::IMU, imu::DELTA_VEL) => put_vec3(out, d.delta_vel_m_s.ok_or(missing)?),
        (group::IMU, imu::MAG) => put_vec3(out, d.mag_gauss.ok_or(missing)?),
        _ => return Err(missing),
    }
    Ok(())
}
