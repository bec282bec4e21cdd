//! Property tests of unit conversions (round trips within half an LSB, saturation) and ticks.

use imu_proto::scale::*;
use imu_proto::ticks::{TICKS_PER_WRAP, TickUnwrapper};
use proptest::prelude::*;

/// Distance between two angles on the circle, in degrees.
fn angle_diff_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1024, ..ProptestConfig::default() })]

    #[test]
    fn scaled_counts_round_trip(raw in any::<i16>(), gain_scale in 1u16..) {
        let q = units_to_scaled(scaled_to_units(raw, gain_scale), gain_scale);
        prop_assert_eq!(q, Quantized { counts: raw, saturated: false });
    }

    #[test]
    fn scaled_quantization_error_is_half_lsb(value in -20.0f64..20.0, gain_scale in 1000u16..20_000) {
        let lsb = f64::from(gain_scale) / GAIN_DIVISOR;
        let q = units_to_scaled(value, gain_scale);
        let back = scaled_to_units(q.counts, gain_scale);
        let max = scaled_to_units(i16::MAX, gain_scale);
        let min = scaled_to_units(i16::MIN, gain_scale);
        if value > max + lsb / 2.0 || value < min - lsb / 2.0 {
            prop_assert!(q.saturated, "{} out of [{}, {}] must saturate", value, min, max);
            prop_assert!(q.counts == i16::MAX || q.counts == i16::MIN);
        } else if (min..=max).contains(&value) {
            prop_assert!(!q.saturated);
            prop_assert!((back - value).abs() <= lsb / 2.0 + 1e-12);
        }
    }

    #[test]
    fn raw_bits_round_trip(raw in any::<u16>(), gain_scale in 1u16..) {
        let q = units_to_raw_bits(raw_bits_to_units(raw, gain_scale), gain_scale);
        prop_assert_eq!(q, Quantized { counts: raw, saturated: false });
    }

    #[test]
    fn quaternion_element_round_trip(value in -4.0f64..3.9998) {
        let q = value_to_quat_matrix_counts(value);
        prop_assert!(!q.saturated);
        prop_assert!((quat_matrix_counts_to_value(q.counts) - value).abs() <= 0.5 / 8192.0 + 1e-12);
    }

    #[test]
    fn euler_any_finite_angle(angle_deg in -1.0e4f64..1.0e4) {
        let q = deg_to_euler_counts(angle_deg);
        prop_assert!(!q.saturated);
        let back = euler_counts_to_deg(q.counts);
        prop_assert!((-180.0..180.0).contains(&back));
        prop_assert!(angle_diff_deg(back, angle_deg) <= 0.5 * 360.0 / 65_536.0 + 1e-9);
    }

    #[test]
    fn temperature_round_trip(raw in any::<u16>(), temp_c in -50.0f64..449.0) {
        prop_assert_eq!(temp_c_to_raw(temp_raw_to_c(raw)), Quantized { counts: raw, saturated: false });
        let q = temp_c_to_raw(temp_c);
        prop_assert!(!q.saturated);
        prop_assert!((temp_raw_to_c(q.counts) - temp_c).abs() <= 0.5 * 500.0 / 65_536.0 + 1e-9);
    }

    #[test]
    fn ticks_unwrap_recovers_true_count(
        start in any::<u16>(),
        steps in prop::collection::vec(0u64..TICKS_PER_WRAP, 1..200),
    ) {
        // Any advance smaller than one wrap between readings is recovered exactly.
        let mut t = TickUnwrapper::new();
        let mut true_ticks = u64::from(start);
        prop_assert_eq!(t.unwrap(start), true_ticks);
        for step in steps {
            true_ticks += step;
            prop_assert_eq!(t.unwrap((true_ticks % TICKS_PER_WRAP) as u16), true_ticks);
        }
        prop_assert_eq!(t.wraps(), true_ticks / TICKS_PER_WRAP);
    }
}
