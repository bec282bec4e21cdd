//! Conversions between device counts and physical units, in both directions.
//!
//! The forward direction (counts -> units) is what the host needs; the inverse (units -> counts,
//! rounded to nearest and saturating) is what the simulator needs to produce replies. Inverse
//! conversions return a [`Quantized`] that says whether the value had to be clipped.

/// Divisor of the scaled-vector formula: value = counts × gain_scale / 32 768 000.
pub const GAIN_DIVISOR: f64 = 32_768_000.0;
/// Raw ADC count taken as zero (mid-scale of the unsigned 16-bit ADC).
pub const RAW_ZERO_COUNTS: u16 = 32_768;
/// Quaternion and orientation-matrix elements: counts per unit.
pub const QUAT_MATRIX_COUNTS_PER_UNIT: f64 = 8192.0;
/// Euler angles: counts per full turn (360°).
pub const EULER_COUNTS_PER_TURN: f64 = 65_536.0;

/// A value converted to device counts, with a flag saying it did not fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Quantized<T> {
    /// The nearest representable count (clipped to the type's range if needed).
    pub counts: T,
    /// True when the value was out of range (or not finite) and `counts` was clipped.
    pub saturated: bool,
}

/// Rounds to nearest and clips into `[min, max]`; NaN becomes 0 and is flagged.
fn quantize(value: f64, min: f64, max: f64) -> (f64, bool) {
    if value.is_nan() {
        return (0.0, true);
    }
    let rounded = value.round();
    if rounded < min {
        (min, true)
    } else if rounded > max {
        (max, true)
    } else {
        (rounded, false)
    }
}

fn quantize_i16(value: f64) -> Quantized<i16> {
    let (v, saturated) = quantize(value, f64::from(i16::MIN), f64::from(i16::MAX));
    Quantized {
        counts: v as i16,
        saturated,
    }
}

fn quantize_u16(value: f64) -> Quantized<u16> {
    let (v, saturated) = quantize(value, 0.0, f64::from(u16::MAX));
    Quantized {
        counts: v as u16,
        saturated,
    }
}

/// Scaled-vector counts (replies 0x02, 0x03, 0x0C, 0x12, 0x31) to units: g, rad/s or gauss
/// depending on the channel whose `gain_scale` is given.
///
/// ```
/// use imu_proto::scale::scaled_to_units;
/// // 4681 counts with accel GainScale 7000 is ~1 g
/// assert!((scaled_to_units(4681, 7000) - 0.99997).abs() < 1e-4);
/// ```
pub fn scaled_to_units(raw: i16, gain_scale: u16) -> f64 {
    f64::from(raw) * f64::from(gain_scale) / GAIN_DIVISOR
}

/// Units to scaled-vector counts (inverse of [`scaled_to_units`]), rounded to nearest and
/// saturated at the i16 range. A zero `gain_scale` makes every non-zero value saturate.
pub fn units_to_scaled(value: f64, gain_scale: u16) -> Quantized<i16> {
    if gain_scale == 0 {
        // Every count maps to 0 units: only 0 is representable.
        return if value == 0.0 {
            Quantized {
                counts: 0,
                saturated: false,
            }
        } else {
            quantize_i16(value * f64::INFINITY)
        };
    }
    quantize_i16(value * GAIN_DIVISOR / f64::from(gain_scale))
}

/// Raw ADC bits (reply 0x01) to units, assuming the nominal scaling
/// `(raw - 32768) × gain_scale / 32 768 000`.
///
/// **Assumption**: the spec only says raw bits are unsigned counts centred *near* 32768 and not
/// orthogonal; the real per-channel zero and gain come from calibration. This nominal mapping
/// is our documented choice so that the simulator and quick looks have a consistent scale.
pub fn raw_bits_to_units(raw: u16, gain_scale: u16) -> f64 {
    (f64::from(raw) - f64::from(RAW_ZERO_COUNTS)) * f64::from(gain_scale) / GAIN_DIVISOR
}

/// Units to raw ADC bits (inverse of [`raw_bits_to_units`], same nominal-scaling assumption),
/// rounded to nearest and saturated at the u16 range.
pub fn units_to_raw_bits(value: f64, gain_scale: u16) -> Quantized<u16> {
    let offset = if gain_scale == 0 {
        if value == 0.0 {
            0.0
        } else {
            value * f64::INFINITY
        }
    } else {
        value * GAIN_DIVISOR / f64::from(gain_scale)
    };
    quantize_u16(offset + f64::from(RAW_ZERO_COUNTS))
}

/// Quaternion or orientation-matrix element counts to a dimensionless value (counts / 8192).
pub fn quat_matrix_counts_to_value(counts: i16) -> f64 {
    f64::from(counts) / QUAT_MATRIX_COUNTS_PER_UNIT
}

/// Quaternion or orientation-matrix element to counts (× 8192), rounded and saturated.
/// Representable range is [-4, 4).
pub fn value_to_quat_matrix_counts(value: f64) -> Quantized<i16> {
    quantize_i16(value * QUAT_MATRIX_COUNTS_PER_UNIT)
}

/// Euler-angle counts to degrees (counts × 360 / 65536), in [-180, 180).
pub fn euler_counts_to_deg(counts: i16) -> f64 {
    f64::from(counts) * 360.0 / EULER_COUNTS_PER_TURN
}

/// Wraps an angle into [-180, 180) degrees.
pub fn wrap_deg(angle_deg: f64) -> f64 {
    let wrapped = (angle_deg + 180.0).rem_euclid(360.0) - 180.0;
    // rem_euclid can return exactly 360.0 for tiny negative inputs due to rounding.
    if wrapped >= 180.0 {
        wrapped - 360.0
    } else {
        wrapped
    }
}

/// Degrees to Euler-angle counts. The angle is first wrapped into [-180, 180), so any finite
/// angle is representable and never saturates (an angle that rounds to +180° becomes -180°,
/// the same orientation). Only a non-finite input is flagged as saturated (counts 0).
pub fn deg_to_euler_counts(angle_deg: f64) -> Quantized<i16> {
    if !angle_deg.is_finite() {
        return Quantized {
            counts: 0,
            saturated: true,
        };
    }
    let counts = (wrap_deg(angle_deg) * EULER_COUNTS_PER_TURN / 360.0).round() as i64;
    // 180° - tiny rounds to +32768, which is -32768 on the circle.
    let counts = (counts + 32_768).rem_euclid(65_536) - 32_768;
    Quantized {
        counts: counts as i16,
        saturated: false,
    }
}

/// Temperature counts (reply 0x07) to °C: ((raw × 5 / 65536) − 0.5) × 100.
///
/// ```
/// use imu_proto::scale::temp_raw_to_c;
/// assert_eq!(temp_raw_to_c(0), -50.0);
/// assert!((temp_raw_to_c(9830) - 24.996).abs() < 1e-3);
/// ```
pub fn temp_raw_to_c(raw: u16) -> f64 {
    (f64::from(raw) * 5.0 / 65_536.0 - 0.5) * 100.0
}

/// °C to temperature counts (inverse of [`temp_raw_to_c`]), rounded and saturated at the u16
/// range (about -50 °C to 450 °C).
pub fn temp_c_to_raw(temp_c: f64) -> Quantized<u16> {
    quantize_u16((temp_c / 100.0 + 0.5) * 65_536.0 / 5.0)
}

/// Splits a firmware version number N into N/1000, (N%1000)/100 and N%100, as the spec reads it.
pub const fn firmware_version_parts(version: u16) -> (u16, u16, u16) {
    (version / 1000, (version % 1000) / 100, version % 100)
}

/// Formats a firmware version number as the spec reads it: `N/1000 . (N%1000)/100 . N%100`,
/// each part a plain decimal number (no zero padding: the spec does not ask for any).
///
/// ```
/// use imu_proto::scale::format_firmware_version;
/// assert_eq!(format_firmware_version(3102), "3.1.2");
/// assert_eq!(format_firmware_version(3145), "3.1.45");
/// ```
pub fn format_firmware_version(version: u16) -> String {
    let (a, b, c) = firmware_version_parts(version);
    format!("{a}.{b}.{c}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_round_trip_within_half_lsb() {
        for gain_scale in [2000u16, 7000, 8500, 10_000] {
            let lsb = f64::from(gain_scale) / GAIN_DIVISOR;
            for raw in [i16::MIN, -12_345, -1, 0, 1, 4681, i16::MAX] {
                let v = scaled_to_units(raw, gain_scale);
                let q = units_to_scaled(v, gain_scale);
                assert_eq!(
                    q,
                    Quantized {
                        counts: raw,
                        saturated: false
                    }
                );
                // perturb by less than half an LSB: same counts
                let q = units_to_scaled(v + 0.49 * lsb, gain_scale);
                assert_eq!(q.counts, raw);
            }
        }
    }

    #[test]
    fn scaled_saturates_and_says_so() {
        // accel gain 7000: full scale is 32767 * 7000 / 32768000 ~ 7.0 g
        assert_eq!(
            units_to_scaled(10.0, 7000),
            Quantized {
                counts: i16::MAX,
                saturated: true
            }
        );
        assert_eq!(
            units_to_scaled(-10.0, 7000),
            Quantized {
                counts: i16::MIN,
                saturated: true
            }
        );
        assert!(units_to_scaled(f64::NAN, 7000).saturated);
        assert!(units_to_scaled(1.0, 0).saturated);
        assert_eq!(
            units_to_scaled(0.0, 0),
            Quantized {
                counts: 0,
                saturated: false
            }
        );
        assert!(!units_to_scaled(6.9, 7000).saturated);
    }

    #[test]
    fn one_g_scale() {
        // 1 g with gain 7000 is 32768000 / 7000 = 4681.14 counts -> 4681
        assert_eq!(units_to_scaled(1.0, 7000).counts, 4681);
        assert!((scaled_to_units(4681, 7000) - 4681.0 * 7000.0 / 32_768_000.0).abs() < 1e-15);
    }

    #[test]
    fn raw_bits_nominal_scaling() {
        assert_eq!(raw_bits_to_units(RAW_ZERO_COUNTS, 7000), 0.0);
        assert_eq!(
            units_to_raw_bits(0.0, 7000),
            Quantized {
                counts: 32_768,
                saturated: false
            }
        );
        for raw in [0u16, 1, 32_767, 32_768, 40_000, u16::MAX] {
            let v = raw_bits_to_units(raw, 8500);
            assert_eq!(
                units_to_raw_bits(v, 8500),
                Quantized {
                    counts: raw,
                    saturated: false
                }
            );
        }
        assert_eq!(
            units_to_raw_bits(100.0, 7000),
            Quantized {
                counts: u16::MAX,
                saturated: true
            }
        );
        assert_eq!(
            units_to_raw_bits(-100.0, 7000),
            Quantized {
                counts: 0,
                saturated: true
            }
        );
    }

    #[test]
    fn quaternion_scale() {
        assert_eq!(quat_matrix_counts_to_value(8192), 1.0);
        assert_eq!(quat_matrix_counts_to_value(-4096), -0.5);
        assert_eq!(
            value_to_quat_matrix_counts(1.0),
            Quantized {
                counts: 8192,
                saturated: false
            }
        );
        assert_eq!(
            value_to_quat_matrix_counts(std::f64::consts::FRAC_1_SQRT_2).counts,
            5793
        );
        assert!(value_to_quat_matrix_counts(4.0).saturated);
        assert!(!value_to_quat_matrix_counts(-4.0).saturated);
    }

    #[test]
    fn euler_scale_and_wrap() {
        assert_eq!(euler_counts_to_deg(16_384), 90.0);
        assert_eq!(euler_counts_to_deg(i16::MIN), -180.0);
        assert_eq!(deg_to_euler_counts(90.0).counts, 16_384);
        assert_eq!(deg_to_euler_counts(-90.0).counts, -16_384);
        // 270° is -90°; 540° is -180°; +180° is -180°
        assert_eq!(deg_to_euler_counts(270.0).counts, -16_384);
        assert_eq!(deg_to_euler_counts(540.0).counts, i16::MIN);
        assert_eq!(deg_to_euler_counts(180.0).counts, i16::MIN);
        // just below +180 rounds to +32768 counts, which wraps to -32768 and is not saturation
        assert_eq!(
            deg_to_euler_counts(179.999),
            Quantized {
                counts: i16::MIN,
                saturated: false
            }
        );
        assert!(deg_to_euler_counts(f64::INFINITY).saturated);
        assert_eq!(wrap_deg(-180.0), -180.0);
        assert_eq!(wrap_deg(180.0), -180.0);
        assert_eq!(wrap_deg(725.0), 5.0);
        // half-LSB round trip
        let lsb = 360.0 / 65_536.0;
        for counts in [i16::MIN, -1, 0, 1, 12_345, i16::MAX] {
            let deg = euler_counts_to_deg(counts);
            assert_eq!(deg_to_euler_counts(deg + 0.49 * lsb).counts, counts);
            assert_eq!(deg_to_euler_counts(deg - 0.49 * lsb).counts, counts);
        }
    }

    #[test]
    fn temperature_formula() {
        assert_eq!(temp_raw_to_c(0), -50.0);
        // raw 13107: 13107 * 5 / 65536 = 0.999985 V -> (0.999985 - 0.5) * 100 = 49.9985 °C
        assert!((temp_raw_to_c(13_107) - 49.9985).abs() < 1e-3);
        // 0.5 V (0 °C) is raw 6553.6
        assert_eq!(temp_c_to_raw(0.0).counts, 6554);
        assert!((temp_raw_to_c(6554) - 0.0).abs() < 100.0 * 5.0 / 65_536.0);
        for raw in [0u16, 1, 6554, 9830, 40_000, u16::MAX] {
            assert_eq!(
                temp_c_to_raw(temp_raw_to_c(raw)),
                Quantized {
                    counts: raw,
                    saturated: false
                }
            );
        }
        assert_eq!(
            temp_c_to_raw(-60.0),
            Quantized {
                counts: 0,
                saturated: true
            }
        );
        assert_eq!(
            temp_c_to_raw(500.0),
            Quantized {
                counts: u16::MAX,
                saturated: true
            }
        );
    }

    #[test]
    fn firmware_version() {
        assert_eq!(firmware_version_parts(3102), (3, 1, 2));
        assert_eq!(format_firmware_version(3102), "3.1.2");
        assert_eq!(format_firmware_version(65_535), "65.5.35");
        assert_eq!(format_firmware_version(0), "0.0.0");
    }
}
