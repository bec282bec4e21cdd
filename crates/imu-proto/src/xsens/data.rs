//! MTData2 (0x36): the data identifiers a calibration needs, decoded into one fixed-size value
//! (no allocation per message) and encoded back in a canonical order, floats in any of the
//! four number formats the identifier's low bits name.

use super::mid::MT_DATA2;
use super::{Message, XsensError};

/// Data identifiers with the float32 format and ENU frame bits (`mtdef.py` `XDIGroup` plus
/// the type nibble; the ids `mtmanager_packets.md` shows on the wire).
pub mod id {
    /// Temperature, degC (1 float).
    pub const TEMPERATURE: u16 = 0x0810;
    /// UTC time: ns u32, year u16, month, day, hour, minute, second, flags u8.
    pub const UTC_TIME: u16 = 0x1010;
    /// Packet counter, u16.
    pub const PACKET_COUNTER: u16 = 0x1020;
    /// Sample time fine: u32 counts of the 10 kHz device clock.
    pub const SAMPLE_TIME_FINE: u16 = 0x1060;
    /// Delta velocity over the output period, m/s (3 floats).
    pub const DELTA_V: u16 = 0x4010;
    /// Acceleration, compensated, m/s^2 (3 floats).
    pub const ACCELERATION: u16 = 0x4020;
    /// Acceleration at the sensors' rate, factory calibration only, m/s^2 (3 floats).
    pub const ACCELERATION_HR: u16 = 0x4040;
    /// Rate of turn, compensated, rad/s (3 floats).
    pub const RATE_OF_TURN: u16 = 0x8020;
    /// Delta quaternion over the output period (4 floats).
    pub const DELTA_Q: u16 = 0x8030;
    /// Rate of turn at the sensors' rate, factory calibration only, rad/s (3 floats).
    pub const RATE_OF_TURN_HR: u16 = 0x8040;
    /// ADC counts of the MTi-10/100 series: 9 x u16 (acc, gyr, mag) and an i16 temperature.
    pub const RAW_ACC_GYR_MAG_TEMP: u16 = 0xA010;
    /// Magnetic field, arbitrary units normalised to the local field (3 floats).
    pub const MAGNETIC_FIELD: u16 = 0xC020;
    /// Status word, u32 bit field.
    pub const STATUS_WORD: u16 = 0xE020;
}

/// The UTC time flags bit saying the time is valid (`mtmanager` "UTC valid").
pub const UTC_VALID: u8 = 0x04;

/// Bits of the status word (0xE020), as the Xsens MT Low-Level Communication Protocol
/// documents them and the vendor SDK's `XsStatusFlag` names them (`XSF_ClipAccX` 0x100 to
/// `XSF_ClipMagZ` 0x10000): each set when that axis's sensor clipped in this sample.
pub mod status {
    /// Accelerometer clipping, x, y, z: bits 8, 9, 10.
    pub const CLIP_ACC: u32 = 0x0000_0700;
    /// Gyroscope clipping, x, y, z: bits 11, 12, 13.
    pub const CLIP_GYR: u32 = 0x0000_3800;
    /// Magnetometer clipping, x, y, z: bits 14, 15, 16.
    pub const CLIP_MAG: u32 = 0x0001_C000;
    /// Any axis of any of the three sensors clipped.
    pub const CLIPPING: u32 = CLIP_ACC | CLIP_GYR | CLIP_MAG;
}

/// The number format of a float item: the identifier's low two bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Format {
    /// IEEE-754 single, 4 bytes.
    #[default]
    Float32,
    /// Fixed point 12.20: i32 / 2^20, 4 bytes.
    Fp1220,
    /// Fixed point 16.32: u32 fraction then i16 integer part, 6 bytes.
    Fp1632,
    /// IEEE-754 double, 8 bytes.
    Float64,
}

impl Format {
    /// Every format, by its bits.
    pub const ALL: [Format; 4] = [
        Format::Float32,
        Format::Fp1220,
        Format::Fp1632,
        Format::Float64,
    ];

    /// The identifier bits.
    pub fn bits(self) -> u16 {
        self as u16
    }

    /// The format of identifier `id`.
    pub fn of(id: u16) -> Self {
        Self::ALL[usize::from(id & 0x0003)]
    }

    /// Bytes per value.
    pub fn size(self) -> usize {
        match self {
            Format::Float32 | Format::Fp1220 => 4,
            Format::Fp1632 => 6,
            Format::Float64 => 8,
        }
    }

    /// Its name in logs and metadata.
    pub fn name(self) -> &'static str {
        match self {
            Format::Float32 => "float32",
            Format::Fp1220 => "fp1220",
            Format::Fp1632 => "fp1632",
            Format::Float64 => "float64",
        }
    }

    fn read(self, b: &[u8]) -> f64 {
        match self {
            Format::Float32 => f64::from(f32::from_be_bytes([b[0], b[1], b[2], b[3]])),
            Format::Fp1220 => f64::from(i32::from_be_bytes([b[0], b[1], b[2], b[3]])) / 1048576.0,
            Format::Fp1632 => {
                let frac = u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
                let int = i16::from_be_bytes([b[4], b[5]]);
                ((i64::from(int) << 32) | i64::from(frac)) as f64 / 4294967296.0
            }
            Format::Float64 => f64::from_be_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }

    /// Appends `v` in this format (fixed point rounds to nearest and saturates).
    fn write(self, v: f64, out: &mut Vec<u8>) {
        match self {
            Format::Float32 => out.extend_from_slice(&(v as f32).to_be_bytes()),
            Format::Fp1220 => {
                out.extend_from_slice(&((v * 1048576.0).round() as i32).to_be_bytes());
            }
            Format::Fp1632 => {
                let fixed = (v * 4294967296.0).round() as i64;
                let fixed = fixed.clamp(
                    i64::from(i16::MIN) << 32,
                    (i64::from(i16::MAX) << 32) | 0xFFFF_FFFF,
                );
                out.extend_from_slice(&(fixed as u32).to_be_bytes());
                out.extend_from_slice(&((fixed >> 32) as i16).to_be_bytes());
            }
            Format::Float64 => out.extend_from_slice(&v.to_be_bytes()),
        }
    }
}

/// A data identifier split into its parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DataId(pub u16);

impl DataId {
    /// The identifier without its format and coordinate bits (what [`id`] lists).
    pub fn base(self) -> u16 {
        self.0 & 0xFFF0
    }

    /// The number format bits.
    pub fn format(self) -> Format {
        Format::of(self.0)
    }

    /// The coordinate frame bits: 0 ENU, 4 NED, 8 NWU.
    pub fn coordinates(self) -> u8 {
        (self.0 & 0x000C) as u8
    }

    /// The identifier of `base` in `format`, ENU.
    pub fn with_format(base: u16, format: Format) -> Self {
        Self((base & 0xFFF0) | format.bits())
    }
}

/// UTC time of the sample (0x1010).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UtcTime {
    /// Nanoseconds into the second.
    pub ns: u32,
    /// Year.
    pub year: u16,
    /// Month, 1..=12.
    pub month: u8,
    /// Day, 1..=31.
    pub day: u8,
    /// Hour.
    pub hour: u8,
    /// Minute.
    pub minute: u8,
    /// Second.
    pub second: u8,
    /// Validity flags ([`UTC_VALID`]: the time is valid).
    pub flags: u8,
}

impl UtcTime {
    /// The unit says the time is valid.
    pub fn valid(&self) -> bool {
        self.flags & UTC_VALID != 0
    }

    /// Unix ns, when the fields make a date.
    pub fn unix_ns(&self) -> Option<i64> {
        crate::gnss_time::utc_fields_to_unix_ns(
            self.year,
            self.month,
            self.day,
            self.hour,
            self.minute,
            self.second,
            self.ns,
        )
    }
}

/// ADC counts of the MTi-10/100 series (0xA010); no published scale.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RawAccGyrMagTemp {
    /// Accelerometer counts.
    pub acc: [u16; 3],
    /// Gyro counts.
    pub gyr: [u16; 3],
    /// Magnetometer counts.
    pub mag: [u16; 3],
    /// Temperature counts.
    pub temp: i16,
}

/// One MTData2 message: each item it carried, `None` for those it did not. Floats are held
/// as f64 whatever their wire format.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MtData2 {
    /// 0x1020.
    pub packet_counter: Option<u16>,
    /// 0x1060, 10 kHz counts.
    pub sample_time_fine: Option<u32>,
    /// 0x1010.
    pub utc: Option<UtcTime>,
    /// 0x0810, degC.
    pub temperature_c: Option<f64>,
    /// 0x4010, m/s.
    pub delta_v_m_s: Option<[f64; 3]>,
    /// 0x4020, m/s^2 (compensated).
    pub acceleration_m_s2: Option<[f64; 3]>,
    /// 0x4040, m/s^2 (factory calibration only).
    pub acceleration_hr_m_s2: Option<[f64; 3]>,
    /// 0x8020, rad/s (compensated).
    pub rate_of_turn_rad_s: Option<[f64; 3]>,
    /// 0x8030, unit quaternion (w, x, y, z).
    pub delta_q: Option<[f64; 4]>,
    /// 0x8040, rad/s (factory calibration only).
    pub rate_of_turn_hr_rad_s: Option<[f64; 3]>,
    /// 0xA010.
    pub raw: Option<RawAccGyrMagTemp>,
    /// 0xC020: the magnetic field normalised to the field where the unit's magnetometer was
    /// calibrated (its magnitude there is 1): a ratio, not gauss or tesla.
    pub magnetic_field_normalised: Option<[f64; 3]>,
    /// 0xE020 ([`status`] names its clipping bits).
    pub status_word: Option<u32>,
    /// Coordinate bits of the last vector item (0 ENU, 4 NED, 8 NWU).
    pub coordinates: u8,
    /// Items of an identifier this codec does not decode, skipped.
    pub unknown_items: u16,
    /// Items of a known identifier with the wrong size for it, skipped.
    pub bad_items: u16,
}

fn floats<const N: usize>(format: Format, data: &[u8]) -> Option<[f64; N]> {
    if data.len() != N * format.size() {
        return None;
    }
    let mut out = [0.0; N];
    for (i, v) in out.iter_mut().enumerate() {
        *v = format.read(&data[i * format.size()..]);
    }
    Some(out)
}

fn be<const N: usize>(data: &[u8]) -> Option<[u8; N]> {
    data.try_into().ok()
}

impl MtData2 {
    /// Decodes an MTData2 message. Unknown items and known ones of the wrong size are
    /// skipped and counted; items that do not tile the data are an error.
    pub fn decode(msg: &Message) -> Result<Self, XsensError> {
        if msg.mid() != MT_DATA2 {
            return Err(XsensError::UnknownMessage(msg.mid()));
        }
        Self::decode_data(msg.data())
    }

    /// Decodes the data of an MTData2 message.
    pub fn decode_data(data: &[u8]) -> Result<Self, XsensError> {
        let mut out = Self::default();
        let mut at = 0;
        while at < data.len() {
            let Some(head) = data.get(at..at + 3) else {
                return Err(XsensError::BadItemLayout { offset: at, id: 0 });
            };
            let id = u16::from_be_bytes([head[0], head[1]]);
            let size = usize::from(head[2]);
            let Some(item) = data.get(at + 3..at + 3 + size) else {
                return Err(XsensError::BadItemLayout { offset: at, id });
            };
            at += 3 + size;
            if !out.item(DataId(id), item) {
                out.bad_items = out.bad_items.saturating_add(1);
            }
        }
        Ok(out)
    }

    /// Takes one item; false when a known id has the wrong size.
    fn item(&mut self, id: DataId, data: &[u8]) -> bool {
        let f = id.format();
        let vector = |this: &mut Self| this.coordinates = id.coordinates();
        macro_rules! set {
            ($field:ident, $value:expr) => {{
                match $value {
                    Some(v) => {
                        self.$field = Some(v);
                        true
                    }
                    None => false,
                }
            }};
        }
        match id.base() {
            id::PACKET_COUNTER => set!(packet_counter, be(data).map(u16::from_be_bytes)),
            id::SAMPLE_TIME_FINE => set!(sample_time_fine, be(data).map(u32::from_be_bytes)),
            id::STATUS_WORD => set!(status_word, be(data).map(u32::from_be_bytes)),
            id::UTC_TIME => set!(
                utc,
                be::<12>(data).map(|b| UtcTime {
                    ns: u32::from_be_bytes([b[0], b[1], b[2], b[3]]),
                    year: u16::from_be_bytes([b[4], b[5]]),
                    month: b[6],
                    day: b[7],
                    hour: b[8],
                    minute: b[9],
                    second: b[10],
                    flags: b[11],
                })
            ),
            id::TEMPERATURE => set!(temperature_c, floats::<1>(f, data).map(|[t]| t)),
            id::DELTA_V => {
                vector(self);
                set!(delta_v_m_s, floats(f, data))
            }
            id::ACCELERATION => {
                vector(self);
                set!(acceleration_m_s2, floats(f, data))
            }
            id::ACCELERATION_HR => {
                vector(self);
                set!(acceleration_hr_m_s2, floats(f, data))
            }
            id::RATE_OF_TURN => {
                vector(self);
                set!(rate_of_turn_rad_s, floats(f, data))
            }
            id::DELTA_Q => {
                vector(self);
                set!(delta_q, floats(f, data))
            }
            id::RATE_OF_TURN_HR => {
                vector(self);
                set!(rate_of_turn_hr_rad_s, floats(f, data))
            }
            id::MAGNETIC_FIELD => {
                vector(self);
                set!(magnetic_field_normalised, floats(f, data))
            }
            id::RAW_ACC_GYR_MAG_TEMP => set!(
                raw,
                be::<20>(data).map(|b| {
                    let w = |i: usize| u16::from_be_bytes([b[2 * i], b[2 * i + 1]]);
                    RawAccGyrMagTemp {
                        acc: [w(0), w(1), w(2)],
                        gyr: [w(3), w(4), w(5)],
                        mag: [w(6), w(7), w(8)],
                        temp: w(9) as i16,
                    }
                })
            ),
            _ => {
                self.unknown_items = self.unknown_items.saturating_add(1);
                true
            }
        }
    }

    /// The data of an MTData2 message with every item present, in identifier order, floats
    /// in `format` (the counters and coordinates are not encoded).
    pub fn encode_data(&self, format: Format) -> Vec<u8> {
        let mut out = Vec::with_capacity(160);
        let item = |out: &mut Vec<u8>, id: u16, size: usize, body: &dyn Fn(&mut Vec<u8>)| {
            out.extend_from_slice(&id.to_be_bytes());
            out.push(size as u8);
            body(out);
        };
        let fl = |id: u16| DataId::with_format(id, format).0;
        let n = format.size();
        if let Some(t) = self.temperature_c {
            item(&mut out, fl(id::TEMPERATURE), n, &|o| format.write(t, o));
        }
        if let Some(u) = self.utc {
            item(&mut out, id::UTC_TIME, 12, &|o| {
                o.extend_from_slice(&u.ns.to_be_bytes());
                o.extend_from_slice(&u.year.to_be_bytes());
                o.extend_from_slice(&[u.month, u.day, u.hour, u.minute, u.second, u.flags]);
            });
        }
        if let Some(c) = self.packet_counter {
            item(&mut out, id::PACKET_COUNTER, 2, &|o| {
                o.extend_from_slice(&c.to_be_bytes())
            });
        }
        if let Some(t) = self.sample_time_fine {
            item(&mut out, id::SAMPLE_TIME_FINE, 4, &|o| {
                o.extend_from_slice(&t.to_be_bytes())
            });
        }
        let vectors: [(u16, Option<&[f64]>); 8] = [
            (id::DELTA_V, self.delta_v_m_s.as_ref().map(|v| &v[..])),
            (
                id::ACCELERATION,
                self.acceleration_m_s2.as_ref().map(|v| &v[..]),
            ),
            (
                id::ACCELERATION_HR,
                self.acceleration_hr_m_s2.as_ref().map(|v| &v[..]),
            ),
            (
                id::RATE_OF_TURN,
                self.rate_of_turn_rad_s.as_ref().map(|v| &v[..]),
            ),
            (id::DELTA_Q, self.delta_q.as_ref().map(|v| &v[..])),
            (
                id::RATE_OF_TURN_HR,
                self.rate_of_turn_hr_rad_s.as_ref().map(|v| &v[..]),
            ),
            (id::RAW_ACC_GYR_MAG_TEMP, None),
            (
                id::MAGNETIC_FIELD,
                self.magnetic_field_normalised.as_ref().map(|v| &v[..]),
            ),
        ];
        for (base, values) in vectors {
            if base == id::RAW_ACC_GYR_MAG_TEMP {
                if let Some(r) = self.raw {
                    item(&mut out, base, 20, &|o| {
                        for w in r.acc.iter().chain(&r.gyr).chain(&r.mag) {
                            o.extend_from_slice(&w.to_be_bytes());
                        }
                        o.extend_from_slice(&r.temp.to_be_bytes());
                    });
                }
                continue;
            }
            if let Some(v) = values {
                item(&mut out, fl(base), n * v.len(), &|o| {
                    for &x in v {
                        format.write(x, o);
                    }
                });
            }
        }
        if let Some(s) = self.status_word {
            item(&mut out, id::STATUS_WORD, 4, &|o| {
                o.extend_from_slice(&s.to_be_bytes())
            });
        }
        out
    }

    /// The MTData2 message (see [`encode_data`](Self::encode_data)).
    pub fn to_message(&self, format: Format) -> Message {
        // At most 13 items of at most 35 bytes: always the standard form.
        Message::new(MT_DATA2, &self.encode_data(format))
            .expect("an MTData2 of the known items fits one message")
    }
}
