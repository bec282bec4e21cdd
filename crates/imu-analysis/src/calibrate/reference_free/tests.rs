//! Tests of the reference-free calibration on simulated poses with a known truth.

use super::*;

/// Deterministic uniform numbers in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn rotation(&mut self) -> UnitQuaternion<f64> {
        let (u1, u2, u3) = (self.next(), self.next(), self.next());
        let tau = std::f64::consts::TAU;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        UnitQuaternion::from_quaternion(imu_model::nalgebra::Quaternion::new(
            b * (tau * u3).cos(),
            a * (tau * u2).sin(),
            a * (tau * u2).cos(),
            b * (tau * u3).sin(),
        ))
    }
}

fn truth() -> Calibration {
    Calibration::from_toml_str(
        r#"
format = "imud-calibration/1"
[accel.misalignment]
xy = 1.2e-3
xz = -0.8e-3
yx = 0.5e-3
yz = 1.5e-3
zx = -1.1e-3
zy = 0.7e-3
[accel.scale]
value = [1.2e-3, -0.8e-3, 1.5e-3]
[accel.bias]
value = [0.25, -0.18, 0.32]
[gyro.misalignment]
xy = -0.9e-3
xz = 1.3e-3
yx = 0.6e-3
yz = -1.0e-3
zx = 0.4e-3
zy = 1.1e-3
[gyro.scale]
value = [2.0e-3, -1.5e-3, 3.0e-3]
[gyro.bias]
value = [8.7e-3, -6.1e-3, 1.05e-2]
"#,
        "truth.toml",
    )
    .unwrap()
}

#[test]
fn truth_in_the_accel_frame_is_the_same_sensor() {
    let t = truth();
    let b = in_accel_frame(&t);
    let m = b.accel.misalignment.as_ref().unwrap();
    assert_eq!((m.xy, m.xz, m.yz), (0.0, 0.0, 0.0));
    // To first order the symmetric part moves to the lower triangle.
    assert!((m.yx - (0.5e-3 + 1.2e-3)).abs() < 1e-5, "{m:?}");
    let mut rng = Lcg(7);
    let c = Conditions::default();
    let q = rng.rotation();
    for _ in 0..5 {
        // The same physical input, expressed in the two frames, gives the same readings:
        // x_body = R x_sensor for one fixed rotation R, found from one accel reading.
        let x = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * 20.0;
        let y = t.accel.forward(x, &c);
        let xb = b.accel.inverse(y, &c);
        assert!((xb.norm() - x.norm()).abs() < 1e-12);
        let w = q * Vec3::new(0.3, -0.2, 0.5);
        let wb_from_gyro = b.gyro.inverse(t.gyro.forward(w, &c), &c);
        let wb_from_accel = b.accel.inverse(t.accel.forward(w, &c), &c);
        // Both triads see the same vector in the body frame (biases aside, equal here).
        let dg = wb_from_gyro - (b.gyro.inverse(t.gyro.forward(Vec3::zeros(), &c), &c));
        let da = wb_from_accel - (b.accel.inverse(t.accel.forward(Vec3::zeros(), &c), &c));
        assert!((dg - da).norm() < 1e-12, "{dg:?} vs {da:?}");
    }
}

/// A synthetic recording through the truth model: `n_poses` orientations from `rng` (or
/// tilts within `max_tilt_rad` of z up), 12 s still each, 2 s moves with a triangular rate
/// profile, tick-quantised timestamps, and a little deterministic noise so that
/// segmentation finds its floor.
fn synthetic(n_poses: usize, max_tilt_rad: Option<f64>, seed: u64) -> (ImuSeries, Calibration) {
    synthetic_sensor(truth(), 12.0, n_poses, max_tilt_rad, seed)
}

/// [`synthetic`] for the sensor `t`, still for `pose_s` at each pose.
fn synthetic_sensor(
    t: Calibration,
    pose_s: f64,
    n_poses: usize,
    max_tilt_rad: Option<f64>,
    seed: u64,
) -> (ImuSeries, Calibration) {
    let mut rng = Lcg(seed);
    let rate_hz = 100.0;
    let dt = 1.0 / rate_hz;
    let up_enu = Vec3::new(0.0, 0.0, STANDARD_GRAVITY_M_S2);
    let mut q = UnitQuaternion::identity();
    let mut series = ImuSeries {
        origin: "synthetic".into(),
        ..ImuSeries::default()
    };
    let c = Conditions::default();
    let push = |series: &mut ImuSeries, q: &UnitQuaternion<f64>, w: Vec3, rng: &mut Lcg| {
        let f = q.inverse_transform_vector(&up_enu);
        let noise = |rng: &mut Lcg, s: f64| {
            Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * s
        };
        let a = t.accel.forward(f, &c) + noise(rng, 2e-3);
        let g = t.gyro.forward(w, &c) + noise(rng, 2e-4);
        // Stamped by a 6.5536 ms tick counter, as the 3DM-GX1's are: integrating over these
        // raw times instead of the fitted line leaves 7x the residual and misses the gains.
        let tick_s = 6.5536e-3;
        series
            .t_s
            .push(((series.t_s.len() as f64 * dt) / tick_s).floor() * tick_s);
        series.accel_m_s2.push(a.into());
        series.gyro_rad_s.push(g.into());
    };
    for p in 0..n_poses {
        for _ in 0..(pose_s * rate_hz).round() as usize {
            push(&mut series, &q, Vec3::zeros(), &mut rng);
        }
        if p + 1 == n_poses {
            break;
        }
        let target = if let Some(max_tilt_rad) = max_tilt_rad {
            let tilt = max_tilt_rad * rng.next();
            let az = std::f64::consts::TAU * rng.next();
            UnitQuaternion::from_scaled_axis(Vec3::new(az.cos(), az.sin(), 0.0) * tilt)
        } else {
            rng.rotation()
        };
        let (axis, angle) = (q.inverse() * target)
            .axis_angle()
            .unwrap_or((Vec3::z_axis(), 0.0));
        let dur_s: f64 = 2.0;
        let alpha = angle / (dur_s / 2.0).powi(2);
        let q0 = q;
        for i in 1..=(dur_s * rate_hz) as usize {
            let tau = i as f64 * dt;
            let (th, rate) = if tau <= dur_s / 2.0 {
                (0.5 * alpha * tau * tau, alpha * tau)
            } else {
                let r = dur_s - tau;
                (angle - 0.5 * alpha * r * r, alpha * r)
            };
            q = q0 * UnitQuaternion::from_axis_angle(&axis, th);
            push(&mut series, &q, axis.into_inner() * rate, &mut rng);
        }
        q = target;
    }
    (series, t)
}

#[test]
fn recovers_a_synthetic_sensor_in_its_accel_frame() {
    let (series, t) = synthetic(20, None, 3);
    let fit = calibrate_reference_free(&series, &ReferenceFreeOptions::default()).unwrap();
    assert_eq!(fit.poses.len(), 20, "{:#?}", fit.segmentation.segments);
    assert_eq!(fit.moves.len(), 19);
    let want = in_accel_frame(&t);
    for (fitted, truth, tol) in [
        (&fit.accel, &want.accel, [1e-4, 2e-5, 2e-5]),
        (&fit.gyro, &want.gyro, [2e-5, 3e-5, 3e-5]),
    ] {
        let tv = truth.params();
        let tn = truth.param_names(fitted.triad);
        for (i, n) in fitted.names.iter().enumerate() {
            let v = tn.iter().position(|x| x == n).map_or(0.0, |k| tv[k]);
            let tol = if n.starts_with("bias") {
                tol[0]
            } else if n.starts_with("scale") {
                tol[1]
            } else {
                tol[2]
            };
            assert!(
                (fitted.params[i] - v).abs() < tol,
                "{} {n}: fit {:e} truth {v:e} se {:?}",
                fitted.triad,
                fitted.params[i],
                fitted.std_errors[i]
            );
        }
    }
    assert_eq!(fit.accel.unobservable.len(), 3, "the gauge");
    assert!(
        fit.accel
            .unobservable
            .iter()
            .all(|u| u.reason == NotFitted::Gauge),
        "{:?}",
        fit.accel.unobservable
    );
    assert!(
        fit.notes.contains(&crate::note::Note::Gauge),
        "{:?}",
        fit.notes
    );
    assert!(fit.accel.warnings.is_empty(), "{:?}", fit.accel.warnings);
    // The calibration file carries its procedure and loads back.
    let text = fit.calibration.to_toml_string();
    let back = Calibration::from_toml_str(&text, "cal.toml").unwrap();
    assert_eq!(back.accel.params(), fit.calibration.accel.params());
    assert!(
        back.provenance
            .procedure
            .unwrap()
            .contains("reference-free")
    );
}

#[test]
fn too_few_or_clustered_poses_say_what_to_record() {
    let (series, _) = synthetic(5, None, 5);
    let e = calibrate_reference_free(&series, &ReferenceFreeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("5 still pose(s) found"), "{e}");
    assert!(e.contains("needs at least 10"), "{e}");
    assert!(e.contains("each axis up and down"), "{e}");

    // Within 20 degrees of one orientation: bias and scale of z are inseparable.
    let (series, _) = synthetic(20, Some(0.35), 5);
    let e = calibrate_reference_free(&series, &ReferenceFreeOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("too clustered"), "{e}");
    assert!(e.contains("bias.z") && e.contains("scale.z"), "{e}");
    assert!(e.contains("each axis up and down"), "{e}");

    // Within 60 degrees: a fit, with warnings naming what the poses lack.
    let (series, _) = synthetic(20, Some(1.05), 5);
    let fit = calibrate_reference_free(&series, &ReferenceFreeOptions::default()).unwrap();
    let w = &fit.accel.warnings;
    assert!(
        w.iter()
            .any(|w| w.scope == WarningScope::Triad(Triad::Accel)
                && matches!(
                    w.kind,
                    FitWarningKind::WeaklySeparated {
                        evidence: Evidence::Poses,
                        ..
                    }
                )),
        "{w:?}"
    );
    let never_pointed: Vec<(usize, bool, bool)> = w
        .iter()
        .filter_map(|w| match w.kind {
            FitWarningKind::AxisNeverPointed { axis, up, down, .. } => Some((axis, up, down)),
            _ => None,
        })
        .collect();
    assert!(never_pointed.iter().any(|&(a, _, _)| a == 0), "{w:?}");
    assert!(never_pointed.contains(&(2, false, true)), "{w:?}");
    // The JSON carries the sentences as before and a code beside each.
    let json = serde_json::to_value(&fit.accel).unwrap();
    let codes = json["warning_codes"].as_array().unwrap();
    assert_eq!(codes.len(), json["warnings"].as_array().unwrap().len());
    assert!(codes.iter().any(|c| c == "axis_never_pointed"), "{json}");
    let z = w
        .iter()
        .find(|w| matches!(w.kind, FitWarningKind::AxisNeverPointed { axis: 2, .. }))
        .unwrap()
        .to_string();
    assert!(
        z.starts_with("accel z: the axis never pointed within 45 degrees of down"),
        "{z}"
    );
}

/// An uncompensated sensor as raw data shows it: accel offsets up to 1 g, scale errors up to
/// 5 %, gyro offsets of 4-9 deg/s.
fn raw_truth() -> Calibration {
    Calibration::from_toml_str(
        r#"
format = "imud-calibration/1"
[accel.misalignment]
xy = 4.0e-3
xz = -2.5e-3
yx = 1.5e-3
yz = 3.5e-3
zx = -3.1e-3
zy = 2.7e-3
[accel.scale]
value = [0.048, -0.035, 0.021]
[accel.bias]
value = [9.5, -6.2, 3.9]
[gyro.misalignment]
xy = -0.9e-3
xz = 1.3e-3
yx = 0.6e-3
yz = -1.0e-3
zx = 0.4e-3
zy = 1.1e-3
[gyro.scale]
value = [0.045, -0.03, 0.012]
[gyro.bias]
value = [0.087, -0.157, 0.07]
"#,
        "raw-truth.toml",
    )
    .unwrap()
}

#[test]
fn raw_offsets_and_short_poses_need_no_preprocessing() {
    // 24 poses of 3 s (2 s of them usable) from a sensor with a 1 g accel offset and a
    // 9 deg/s gyro offset: the fit starts from the closed-form ellipsoid and recovers the truth.
    let (series, t) = synthetic_sensor(raw_truth(), 3.0, 24, None, 11);
    let fit = calibrate_reference_free(&series, &ReferenceFreeOptions::default()).unwrap();
    assert_eq!(fit.poses.len(), 24, "{:#?}", fit.segmentation.segments);
    let want = in_accel_frame(&t);
    for (fitted, truth) in [(&fit.accel, &want.accel), (&fit.gyro, &want.gyro)] {
        let tv = truth.params();
        let tn = truth.param_names(fitted.triad);
        for (i, n) in fitted.names.iter().enumerate() {
            let v = tn.iter().position(|x| x == n).map_or(0.0, |k| tv[k]);
            // Held parameters (the gauge) have no standard error.
            let Some(se) = fitted.std_errors[i] else {
                continue;
            };
            assert!(
                (fitted.params[i] - v).abs() < 4.0 * se + 1e-9,
                "{} {n}: fit {:e} truth {v:e} se {se:e}",
                fitted.triad,
                fitted.params[i],
            );
        }
    }
    assert!(fit.notes.has("gyro_rest_rate"), "{:?}", fit.notes.codes());
    let notes = fit.notes.sentences().join("\n");
    assert!(notes.contains("deg/s at rest"), "{notes}");
}

/// The moves integrated on several threads, each with its rate corrected as one batch, give
/// bit-for-bit the residuals of the sample-by-sample integration on one thread (the gain fits
/// and the workbench's candidates depend on it being the same computation).
#[test]
fn parallel_batch_integration_of_the_moves_is_bit_identical_to_sample_by_sample() {
    let mut rng = Lcg(11);
    let mut gains = TriadModel::with_effects(&[
        EffectKind::Misalignment,
        EffectKind::Scale,
        EffectKind::AsymmetricScale,
        EffectKind::ScaleNonlinearity,
    ]);
    let p: Vec<f64> = (0..gains.n_params())
        .map(|_| 4e-3 * (rng.next() - 0.5))
        .collect();
    gains.set_params(&p);
    let moves: Vec<MoveData> = (0..37)
        .map(|k| {
            let up = rng.rotation() * Vec3::z();
            let (e1, e2) = normal_basis(rng.rotation() * Vec3::z());
            let axis = (rng.rotation() * Vec3::x()) * 2.0;
            MoveData {
                from_pose: k,
                to_pose: k + 1,
                rate_rad_s: (0..150 + k)
                    .map(|i| axis * (std::f64::consts::PI * i as f64 / 150.0).sin())
                    .collect(),
                step_s: 0.01,
                up_before: up,
                e1,
                e2,
                conditions: Conditions::default(),
                sigma_rad: 1e-3,
            }
        })
        .collect();
    let sample_by_sample = |m: &MoveData| -> [f64; 2] {
        let mut q = UnitQuaternion::identity();
        let mut w0 = gains.inverse(m.rate_rad_s[0], &m.conditions);
        for r in &m.rate_rad_s[1..] {
            let w1 = gains.inverse(*r, &m.conditions);
            q *= UnitQuaternion::from_scaled_axis((w0 + w1) * (0.5 * m.step_s));
            w0 = w1;
        }
        let predicted = q.inverse_transform_vector(&m.up_before);
        [m.e1.dot(&predicted), m.e2.dot(&predicted)]
    };
    let want: Vec<[f64; 2]> = moves.iter().map(sample_by_sample).collect();
    let got = move_residuals(&moves, &gains);
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.map(f64::to_bits), w.map(f64::to_bits), "{g:?} vs {w:?}");
    }
    // Not vacuous: the gains turn the predicted direction measurably.
    assert!(want.iter().any(|r| r[0].abs() > 1e-6));

    // With the first inverse stage (the nonlinearity) kept between evaluations: a change of
    // another stage's parameter reuses it, a change of its own recomputes it; every result is
    // bit-for-bit the sample-by-sample one.
    let mut cache = None;
    let n = gains.n_params();
    for (step, i) in [(0, 0), (1, 0), (2, 1), (3, n - 1), (4, 2)] {
        let mut q = p.clone();
        q[i] += 1e-4 * step as f64;
        let mut g = gains.clone();
        g.set_params(&q);
        let got = move_residuals_cached(&moves, &g, &mut cache);
        for (m, r) in moves.iter().zip(&got) {
            let w = {
                let mut q = UnitQuaternion::identity();
                let mut w0 = g.inverse(m.rate_rad_s[0], &m.conditions);
                for x in &m.rate_rad_s[1..] {
                    let w1 = g.inverse(*x, &m.conditions);
                    q *= UnitQuaternion::from_scaled_axis((w0 + w1) * (0.5 * m.step_s));
                    w0 = w1;
                }
                let predicted = q.inverse_transform_vector(&m.up_before);
                [m.e1.dot(&predicted), m.e2.dot(&predicted)]
            };
            assert_eq!(r.map(f64::to_bits), w.map(f64::to_bits), "step {step}");
        }
    }
}
