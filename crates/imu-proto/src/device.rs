//! Device parameters that the drivers disagree about, as plain configurable data.

use crate::command::Command;
use crate::ticks::DEFAULT_TICK_PERIOD_S;

/// EEPROM word address of the gyro GainScale (read with 0x28).
pub const GYRO_GAIN_SCALE_ADDR: u16 = 130;
/// EEPROM word address of the accelerometer GainScale.
pub const ACCEL_GAIN_SCALE_ADDR: u16 = 230;
/// EEPROM word address of the magnetometer GainScale.
pub const MAG_GAIN_SCALE_ADDR: u16 = 232;
/// Factory-default baud rate in most drivers (one driver uses 115200).
pub const DEFAULT_BAUD: u32 = 38_400;

/// The three GainScale words used in value = counts × gain_scale / 32 768 000.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct GainScales {
    /// Accelerometer GainScale (result in g).
    pub accel: u16,
    /// Gyro GainScale (result in rad/s).
    pub gyro: u16,
    /// Magnetometer GainScale (result in gauss).
    pub mag: u16,
}

impl GainScales {
    /// Our default fallback: accel 7000, gyro 10000, mag 2000.
    ///
    /// **Disputed**: drivers use accel 7000 or 8500 and gyro 8500 or 10000 (mag 2000 in all).
    /// The real values are in the device's EEPROM ([`GainScales::read_commands`]). A fallback
    /// must never be used silently: whoever falls back has to say so in the log and in the
    /// recording's metadata.
    pub const DEFAULT_FALLBACK: GainScales = GainScales {
        accel: 7000,
        gyro: 10_000,
        mag: 2000,
    };

    /// The EEPROM reads that fetch the real values, in the order accel, gyro, mag.
    pub const fn read_commands() -> [Command; 3] {
        [
            Command::ReadEeprom {
                address: ACCEL_GAIN_SCALE_ADDR,
            },
            Command::ReadEeprom {
                address: GYRO_GAIN_SCALE_ADDR,
            },
            Command::ReadEeprom {
                address: MAG_GAIN_SCALE_ADDR,
            },
        ]
    }
}

/// Per-device parameters whose right value is disputed between drivers or set per installation.
///
/// [`Default`] gives the majority values. They are data, not hidden constants: the daemon reads
/// them from its config and records the values in force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceParams {
    /// Seconds per timer tick (default 6.5536 ms; one driver uses 10 ms).
    pub tick_period_s: f64,
    /// Serial baud rate (default 38400; one driver uses 115200).
    pub baud: u32,
    /// GainScales to use if the EEPROM read fails. Never use them silently.
    pub fallback_gains: GainScales,
}

impl Default for DeviceParams {
    fn default() -> Self {
        Self {
            tick_period_s: DEFAULT_TICK_PERIOD_S,
            baud: DEFAULT_BAUD,
            fallback_gains: GainScales::DEFAULT_FALLBACK,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn documented_defaults() {
        let p = DeviceParams::default();
        assert_eq!(p.tick_period_s, 6.5536e-3);
        assert_eq!(p.baud, 38_400);
        assert_eq!(
            p.fallback_gains,
            GainScales {
                accel: 7000,
                gyro: 10_000,
                mag: 2000
            }
        );
    }

    #[test]
    fn gain_reads_hit_the_documented_addresses() {
        let bytes: Vec<Vec<u8>> = GainScales::read_commands()
            .iter()
            .map(Command::to_bytes)
            .collect();
        // 230 = 0x00E6, 130 = 0x0082, 232 = 0x00E8
        assert_eq!(
            bytes,
            vec![
                vec![0x28, 0x00, 0xE6],
                vec![0x28, 0x00, 0x82],
                vec![0x28, 0x00, 0xE8]
            ]
        );
    }
}
