//! The pipeline's per-sample correction on messy input.

use std::sync::Arc;

use imu_model::{Calibration, Measured, Vec3};

use super::{
    Acquisition, ActiveCalibration, Gains, Pipeline, SessionSpec, TickKind, TickLength, Timebase,
};

/// A unit that sends NaN for one angular rate: that sample is NaN, and the samples after it
/// are corrected as if it had not come (the lever-arm term's angular acceleration is the
/// difference of the last two finite rates), not poisoned by it.
#[test]
fn a_nan_rate_spoils_its_own_sample_only() {
    let cal = Calibration::from_toml_str(
        "format = \"imud-calibration/1\"\n\
         [accel.lever-arm]\noffset-m = [0.05, -0.02, 0.03]\n\
         [accel.bias]\nvalue = [0.01, 0.02, -0.03]\n",
        "lever arm",
    )
    .unwrap();
    let active = Some(Arc::new(ActiveCalibration::new(cal)));
    // A streaming unit with a 1 us clock (the pipeline knows no protocol).
    let session = SessionSpec {
        gains: Gains::NOT_APPLICABLE,
        timebase: Timebase {
            tick: TickLength::WholeNs(1_000),
            kind: TickKind::Fine,
        },
        acquisition: Acquisition::Streaming,
        status_protocol: 0,
        configuration_verified: false,
    };
    let sample = |k: u64| Measured {
        accel_m_s2: Vec3::new(0.1 * k as f64, -0.2, 9.8),
        gyro_rad_s: Vec3::new(0.01 * k as f64, 0.02, -0.5 + 0.03 * k as f64),
        mag_gauss: Vec3::repeat(f64::NAN),
    };
    let dt_ns = 10_000_000;
    let run = |nan_at: Option<u64>| -> Vec<[f64; 3]> {
        let mut p = Pipeline::new(session, active.clone());
        (0..8u64)
            .map(|k| {
                let mut m = sample(k);
                if Some(k) == nan_at {
                    m.gyro_rad_s[1] = f64::NAN;
                }
                p.correct(&m, k * dt_ns, k * dt_ns).accel_m_s2
            })
            .collect()
    };
    let clean = run(None);
    let holed = run(Some(3));
    assert!(holed[3].iter().any(|v| v.is_nan()), "{:?}", holed[3]);
    for k in [0, 1, 2, 4, 5, 6, 7] {
        assert!(
            holed[k].iter().all(|v| v.is_finite()),
            "sample {k}: {:?}",
            holed[k]
        );
    }
    // Before the NaN, and once two finite rates follow it, exactly the clean correction; just
    // after it, the rate's difference spans the skipped sample (the same on this linear ramp).
    for k in [0, 1, 2, 6, 7] {
        assert_eq!(holed[k], clean[k], "sample {k}");
    }
    for k in [4, 5] {
        for i in 0..3 {
            assert!(
                (holed[k][i] - clean[k][i]).abs() <= 1e-12 * clean[k][i].abs().max(1.0),
                "sample {k}: {:?} vs {:?}",
                holed[k],
                clean[k]
            );
        }
    }
}
