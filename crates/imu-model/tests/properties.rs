//! Property tests (proptest): the nonlinearity inverse over its whole valid domain, and exact
//! TOML round trips of arbitrary finite parameter values.

use imu_model::{
    Bias, Calibration, Conditions, Effect, ScaleNonlinearity, Triad, TriadModel, Vec3,
};
use proptest::prelude::*;

proptest! {
    /// Any (k2, k3) that validation accepts for the gyro is inverted to ~machine precision
    /// anywhere inside the validation range.
    #[test]
    fn nonlinearity_inverse_is_exact_where_valid(
        k2 in -6e-3f64..6e-3,
        k3 in -3e-4f64..3e-4,
        frac in -1.0f64..1.0,
    ) {
        let nl = ScaleNonlinearity { quadratic: [k2; 3], cubic: [k3; 3], std_error: None };
        let model = TriadModel { scale_nonlinearity: Some(nl.clone()), ..Default::default() };
        prop_assume!(model.validate(Triad::Gyro).is_ok());
        let x = frac * Triad::Gyro.validation_range();
        let c = Conditions::default();
        let back = nl.inverse(nl.forward(Vec3::repeat(x), &c), &c);
        // The conditioning is 1/gain <= 2 and a few roundings happen in forward.
        prop_assert!((back[0] - x).abs() <= 16.0 * f64::EPSILON * x.abs().max(f64::MIN_POSITIVE), "{} vs {}", back[0], x);
    }

    /// The quadratic-only curve (k3 = 0, closed-form inverse) likewise, and beyond its turning
    /// point the inverse saturates at the turning point.
    #[test]
    fn quadratic_nonlinearity_inverse_is_exact_where_valid(
        k2 in -6e-3f64..6e-3,
        frac in -1.0f64..1.0,
    ) {
        let nl = ScaleNonlinearity { quadratic: [k2; 3], cubic: [0.0; 3], std_error: None };
        let model = TriadModel { scale_nonlinearity: Some(nl.clone()), ..Default::default() };
        prop_assume!(model.validate(Triad::Gyro).is_ok());
        let x = frac * Triad::Gyro.validation_range();
        let c = Conditions::default();
        let back = nl.inverse(nl.forward(Vec3::repeat(x), &c), &c);
        prop_assert!((back[0] - x).abs() <= 16.0 * f64::EPSILON * x.abs().max(f64::MIN_POSITIVE), "{} vs {}", back[0], x);
        if k2 != 0.0 {
            let turning_x = -1.0 / (2.0 * k2);
            let beyond = nl.forward(Vec3::repeat(turning_x), &c)[0] * (1.0 + frac.abs()) + turning_x.signum() * 1e-3 * (1.0 - frac.abs());
            let sat = nl.inverse(Vec3::repeat(beyond), &c)[0];
            prop_assert!((sat - turning_x).abs() <= 1e-12 * turning_x.abs(), "{sat} vs {turning_x}");
        }
        prop_assert!(nl.inverse(Vec3::repeat(f64::NAN), &c)[0].is_nan());
    }

    /// Values of any magnitude survive to_toml_string -> from_toml_str bit for bit.
    #[test]
    fn toml_round_trip_is_bit_exact(
        v in prop::array::uniform3(prop_oneof![
            -1e3f64..1e3,
            (-300i32..300).prop_map(|e| 1.234_567_890_123_456_7 * 10f64.powi(e)),
            Just(0.0),
            Just(-0.0),
        ]),
    ) {
        let mut cal = Calibration::identity();
        cal.gyro.bias = Some(Bias { value: v, std_error: None });
        let back = Calibration::from_toml_str(&cal.to_toml_string(), "prop.toml").expect("parses");
        let got = back.gyro.bias.as_ref().expect("present").value;
        for i in 0..3 {
            prop_assert_eq!(got[i].to_bits(), v[i].to_bits());
        }
        prop_assert_eq!(back.content_id(), cal.content_id());
    }
}
