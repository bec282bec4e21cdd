//! The IMU data set (0x80): the fields a calibration needs, decoded into one fixed-size value
//! (no allocation per packet) and encoded back in a canonical order.

use super::descriptor_set::IMU_DATA;
use super::packet::{Field, Reader};
use super::{MipError, Packet, PacketBuilder};

/// IMU data field descriptors (mip_sdk `data_sensor.h`, `data_shared.h`).
pub mod field {
    /// Raw accel, native sensor counts (3 x f32).
    pub const RAW_ACCEL: u8 = 0x01;
    /// Raw gyro, native sensor counts (3 x f32).
    pub const RAW_GYRO: u8 = 0x02;
    /// Raw mag, native sensor counts (3 x f32).
    pub const RAW_MAG: u8 = 0x03;
    /// Scaled accel, g (3 x f32).
    pub const SCALED_ACCEL: u8 = 0x04;
    /// Scaled gyro, rad/s (3 x f32).
    pub const SCALED_GYRO: u8 = 0x05;
    /// Scaled mag, gauss (3 x f32).
    pub const SCALED_MAG: u8 = 0x06;
    /// Delta theta, rad over the output period (3 x f32).
    pub const DELTA_THETA: u8 = 0x07;
    /// Delta velocity, g*s over the output period (3 x f32).
    pub const DELTA_VELOCITY: u8 = 0x08;
    /// Internal timestamp, u32 counts (deprecated; see [`super::INTERNAL_TICK_HZ`]).
    pub const INTERNAL_TIMESTAMP: u8 = 0x0E;
    /// GPS timestamp: time of week f64 s, week u16, valid flags u16.
    pub const GPS_TIMESTAMP: u8 = 0x12;
    /// Temperature statistics since power-on: min, max, mean f32 degC.
    pub const TEMPERATURE_ABS: u8 = 0x14;
    /// Shared field: reference time, u64 ns since the device started.
    pub const REFERENCE_TIME: u8 = 0xD5;
}

/// Rate of the internal timestamp counter (0x0E), from the 3DM-GX3-25 manual (16 us per count);
/// the SDK does not state it.
pub const INTERNAL_TICK_HZ: f64 = 62_500.0;

/// GPS time of the sample (0x12).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GpsTime {
    /// Time of week, s.
    pub tow_s: f64,
    /// Weeks since 1980-01-06.
    pub week: u16,
    /// Validity bits (1 PPS valid, 2 time refreshed, 4 initialised, 8 TOW valid, 16 week valid).
    pub valid_flags: u16,
}

/// Temperature since power-on (0x14), degC.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TemperatureStats {
    /// Lowest, degC.
    pub min_c: f32,
    /// Highest, degC.
    pub max_c: f32,
    /// Mean, degC.
    pub mean_c: f32,
}

/// One IMU data packet: each field it carried, `None` for those it did not.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ImuData {
    /// 0x01, native counts.
    pub raw_accel: Option<[f32; 3]>,
    /// 0x02, native counts.
    pub raw_gyro: Option<[f32; 3]>,
    /// 0x03, native counts.
    pub raw_mag: Option<[f32; 3]>,
    /// 0x04, g.
    pub accel_g: Option<[f32; 3]>,
    /// 0x05, rad/s.
    pub gyro_rad_s: Option<[f32; 3]>,
    /// 0x06, gauss.
    pub mag_gauss: Option<[f32; 3]>,
    /// 0x07, rad.
    pub delta_theta_rad: Option<[f32; 3]>,
    /// 0x08, g*s.
    pub delta_velocity_g_s: Option<[f32; 3]>,
    /// 0x0E, counts at [`INTERNAL_TICK_HZ`].
    pub internal_ticks: Option<u32>,
    /// 0x12.
    pub gps_time: Option<GpsTime>,
    /// 0x14.
    pub temperature: Option<TemperatureStats>,
    /// 0xD5, ns since the device started.
    pub reference_time_ns: Option<u64>,
    /// Fields skipped: unknown descriptors, or known ones of an unexpected size (not encoded).
    pub skipped_fields: u8,
}

/// Most bytes one field's data has here (the GPS timestamp's 12, the vectors' 12, ...).
const MAX_DATA: usize = 12;

fn vec3_bytes(v: [f32; 3]) -> [u8; MAX_DATA] {
    let mut out = [0u8; MAX_DATA];
    for (chunk, x) in out.chunks_exact_mut(4).zip(v) {
        chunk.copy_from_slice(&x.to_be_bytes());
    }
    out
}

impl ImuData {
    fn vectors(&self) -> [(u8, Option<[f32; 3]>); 8] {
        [
            (field::RAW_ACCEL, self.raw_accel),
            (field::RAW_GYRO, self.raw_gyro),
            (field::RAW_MAG, self.raw_mag),
            (field::SCALED_ACCEL, self.accel_g),
            (field::SCALED_GYRO, self.gyro_rad_s),
            (field::SCALED_MAG, self.mag_gauss),
            (field::DELTA_THETA, self.delta_theta_rad),
            (field::DELTA_VELOCITY, self.delta_velocity_g_s),
        ]
    }

    /// The packet (device side): fields in descriptor order, the shared reference time last.
    pub fn to_packet(&self) -> Packet {
        let mut b = PacketBuilder::new(IMU_DATA);
        // Every field at once is 8 x 14 + 6 + 14 + 14 + 10 = 156 bytes: `field` cannot fail.
        for (d, v) in self.vectors() {
            if let Some(v) = v {
                let _ = b.field(d, &vec3_bytes(v));
            }
        }
        if let Some(t) = self.internal_ticks {
            let _ = b.field(field::INTERNAL_TIMESTAMP, &t.to_be_bytes());
        }
        if let Some(g) = self.gps_time {
            let mut data = [0u8; MAX_DATA];
            data[..8].copy_from_slice(&g.tow_s.to_be_bytes());
            data[8..10].copy_from_slice(&g.week.to_be_bytes());
            data[10..].copy_from_slice(&g.valid_flags.to_be_bytes());
            let _ = b.field(field::GPS_TIMESTAMP, &data);
        }
        if let Some(t) = self.temperature {
            let _ = b.field(
                field::TEMPERATURE_ABS,
                &vec3_bytes([t.min_c, t.max_c, t.mean_c]),
            );
        }
        if let Some(ns) = self.reference_time_ns {
            let _ = b.field(field::REFERENCE_TIME, &ns.to_be_bytes());
        }
        b.build()
    }

    /// Decodes an IMU data packet (host side). Unknown fields, and known ones whose size is
    /// not the documented one, are skipped and counted in `skipped_fields`; a repeated field
    /// keeps its last value.
    pub fn decode_packet(packet: &Packet) -> Result<Self, MipError> {
        let set = packet.descriptor_set();
        if set != IMU_DATA {
            return Err(MipError::WrongDescriptorSet {
                expected: IMU_DATA,
                found: set,
            });
        }
        let mut out = Self::default();
        for f in packet.fields() {
            if out.apply(f).is_err() {
                out.skipped_fields = out.skipped_fields.saturating_add(1);
            }
        }
        Ok(out)
    }

    /// Stores one field; `Err` when it is unknown or of the wrong size.
    fn apply(&mut self, f: Field<'_>) -> Result<(), MipError> {
        let mut r = Reader::new(IMU_DATA, f);
        let slot = match f.descriptor {
            field::RAW_ACCEL => &mut self.raw_accel,
            field::RAW_GYRO => &mut self.raw_gyro,
            field::RAW_MAG => &mut self.raw_mag,
            field::SCALED_ACCEL => &mut self.accel_g,
            field::SCALED_GYRO => &mut self.gyro_rad_s,
            field::SCALED_MAG => &mut self.mag_gauss,
            field::DELTA_THETA => &mut self.delta_theta_rad,
            field::DELTA_VELOCITY => &mut self.delta_velocity_g_s,
            field::INTERNAL_TIMESTAMP => {
                let t = r.u32()?;
                r.end()?;
                self.internal_ticks = Some(t);
                return Ok(());
            }
            field::GPS_TIMESTAMP => {
                let g = GpsTime {
                    tow_s: r.f64()?,
                    week: r.u16()?,
                    valid_flags: r.u16()?,
                };
                r.end()?;
                self.gps_time = Some(g);
                return Ok(());
            }
            field::TEMPERATURE_ABS => {
                let [min_c, max_c, mean_c] = r.vec3()?;
                r.end()?;
                self.temperature = Some(TemperatureStats {
                    min_c,
                    max_c,
                    mean_c,
                });
                return Ok(());
            }
            field::REFERENCE_TIME => {
                let ns = r.u64()?;
                r.end()?;
                self.reference_time_ns = Some(ns);
                return Ok(());
            }
            _ => return Err(r.error("unknown field")),
        };
        let v = r.vec3()?;
        r.end()?;
        *slot = Some(v);
        Ok(())
    }
}
