//! Tests of the least-squares engine on problems with known answers.

use nalgebra::DVector;

use super::*;
/// A straight line through noisy points: the fit, its standard errors (scaled by the
/// scatter) and an unobservable duplicate parameter.
#[test]
fn fits_a_line_and_names_a_duplicate_parameter() {
    let xs: Vec<f64> = (0..20).map(|i| i as f64).collect();
    // Deterministic +/-0.5 scatter, so the reduced chi-square with sigma = 0.1 is large.
    let ys: Vec<f64> = xs
        .iter()
        .enumerate()
        .map(|(i, x)| 2.0 + 0.5 * x + if i % 2 == 0 { 0.5 } else { -0.5 })
        .collect();
    let sigma = 0.1;
    let f = |p: &[f64]| {
        DVector::from_iterator(
            xs.len(),
            xs.iter()
                .zip(&ys)
                .map(|(x, y)| (p[0] + p[2] + p[1] * x - y) / sigma),
        )
    };
    let names: Vec<String> = ["a", "b", "a2"].iter().map(|s| s.to_string()).collect();
    let s = least_squares(f, &[0.0, 0.0, 0.0], &[], &names, &LsqOptions::default()).unwrap();
    assert_eq!(s.free, vec![0, 1]);
    assert_eq!(s.unobservable.len(), 1);
    assert_eq!(s.unobservable[0].name, "a2");
    let NotFitted::Collinear { with, .. } = &s.unobservable[0].reason else {
        panic!("{:?}", s.unobservable)
    };
    assert_eq!(with, &["a"]);
    assert!((s.params[1] - 0.5).abs() < 0.01, "{:?}", s.params);
    assert!((s.params[0] - 2.0).abs() < 0.3, "{:?}", s.params);
    assert_eq!(s.std_errors[2], None);
    // Ordinary least squares of a line: se(b) = s / sqrt(sum (x - mean)^2), with s the
    // residual standard deviation (the chi-square scaling replaces the stated 0.1).
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let sxx: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
    let res_sd = (s.chi2 / s.dof as f64).sqrt() * sigma;
    let want = res_sd / sxx.sqrt();
    assert!(
        (s.std_errors[1].unwrap() / want - 1.0).abs() < 1e-4,
        "{:?} vs {want}",
        s.std_errors[1]
    );
    assert!(s.reduced_chi2 > 10.0);
    assert!(s.converged);

    let e = least_squares(
        |p: &[f64]| DVector::from_vec(vec![p[0] - 1.0, p[1] - 2.0]),
        &[0.0, 0.0],
        &[],
        &names[..2],
        &LsqOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, LsqError::TooFewResiduals { .. }), "{e}");
}

/// Holding a rejected parameter at 0 and refitting: the loop ends when the caller accepts,
/// with what was held in order.
#[test]
fn refit_holding_holds_what_the_caller_rejects() {
    let xs: Vec<f64> = (0..30).map(|i| i as f64 / 10.0).collect();
    // y = 1 + 2 x exactly; a quadratic term would fit to ~0 but the caller forbids any value
    // of it (say, a model that must stay monotonic), so it is held.
    let ys: Vec<f64> = xs.iter().map(|x| 1.0 + 2.0 * x).collect();
    let names: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
    let (sol, held) = refit_holding(
        |held: &[usize]| {
            let fixed: Vec<bool> = (0..3).map(|i| held.contains(&i)).collect();
            let f = |p: &[f64]| {
                DVector::from_iterator(
                    xs.len(),
                    xs.iter()
                        .zip(&ys)
                        .map(|(x, y)| (p[0] + p[1] * x + p[2] * x * x - y) / 0.01),
                )
            };
            least_squares(f, &[0.0, 0.0, 0.0], &fixed, &names, &LsqOptions::default())
        },
        |s: &LsqSolution, held: &[usize]| {
            Ok((!held.contains(&2) && s.params[2] != 0.0).then_some(2))
        },
    )
    .unwrap();
    assert_eq!(held, vec![2]);
    assert_eq!(sol.params[2], 0.0);
    assert_eq!(sol.free, vec![0, 1]);
    assert!((sol.params[1] - 2.0).abs() < 1e-9);
}

/// A collinear parameter's reason carries the caller's advice.
#[test]
fn collinear_advice_is_appended() {
    let names: Vec<String> = ["a", "b"].iter().map(|s| s.to_string()).collect();
    let opts = LsqOptions {
        collinear_advice: "; vary the input".into(),
        ..LsqOptions::default()
    };
    let f = |p: &[f64]| DVector::from_iterator(5, (0..5).map(|i| p[0] + p[1] - i as f64));
    let s = least_squares(f, &[0.0, 0.0], &[], &names, &opts).unwrap();
    assert_eq!(s.unobservable[0].name, "b");
    let NotFitted::Collinear { advice, .. } = &s.unobservable[0].reason else {
        panic!("{:?}", s.unobservable)
    };
    assert_eq!(advice, "; vary the input");
    // The sentence for people ends with the advice; the JSON carries the code beside it.
    let text = s.unobservable[0].reason.to_string();
    assert!(text.ends_with("matrix); vary the input"), "{text}");
    let json = serde_json::to_value(&s.unobservable[0]).unwrap();
    assert_eq!(json["code"], "collinear");
    assert_eq!(json["name"], "b");
    assert_eq!(json["reason"], text);
}

/// A parameter the residuals do not depend on is held with the typed reason (not a sentence a
/// caller has to search), and its JSON carries the stable code beside the sentence.
#[test]
fn a_parameter_the_data_ignore_is_held_as_zero_jacobian() {
    let names: Vec<String> = ["a", "unused"].iter().map(|s| s.to_string()).collect();
    let f = |p: &[f64]| DVector::from_iterator(4, (0..4).map(|i| p[0] - i as f64));
    let s = least_squares(f, &[0.0, 7.0], &[], &names, &LsqOptions::default()).unwrap();
    assert_eq!(s.free, vec![0]);
    assert_eq!(s.unobservable.len(), 1);
    assert_eq!(s.unobservable[0].name, "unused");
    assert_eq!(s.unobservable[0].reason, NotFitted::ZeroJacobian);
    assert_eq!(s.params[1], 7.0);
    let json = serde_json::to_value(&s.unobservable[0]).unwrap();
    assert_eq!(json["code"], "zero_jacobian");
    assert_eq!(
        json["reason"],
        "the data do not excite it (zero Jacobian column)"
    );
}

/// Every reason has its own code, and the codes are the documented strings.
#[test]
fn not_fitted_codes_are_stable() {
    let all = [
        (NotFitted::ZeroJacobian, "zero_jacobian"),
        (
            NotFitted::Collinear {
                with: vec![],
                eigenvalue: 1e-12,
                advice: String::new(),
            },
            "collinear",
        ),
        (NotFitted::Gauge, "gauge"),
        (NotFitted::Requested, "requested"),
        (
            NotFitted::InvalidModel {
                value: 1.0,
                std_error: Some(0.5),
                message: "not invertible".into(),
            },
            "invalid_model",
        ),
    ];
    for (reason, code) in &all {
        assert_eq!(reason.code(), *code);
    }
    let text = all[4].0.to_string();
    assert_eq!(
        text,
        "fitted to 1.000e0 +/- 5.00e-1, it makes the model invalid (not invertible); held at 0 \
         (no such term)"
    );
}

/// The fit reuses the Jacobian it checked observability with, the start's residuals and, when
/// the search ends on it, the last Jacobian: its solution is bit-for-bit that of the steps done
/// one by one (observability, minimisation, a fresh Jacobian at the minimum), and it evaluates
/// the residuals fewer times. The problem has a zero column and a collinear pair to drop, and
/// is nonlinear (an exponential decay), so the search takes several steps.
#[test]
fn reusing_jacobians_changes_no_bit_of_the_solution() {
    let ts: Vec<f64> = (0..40).map(|i| 0.25 * i as f64).collect();
    let ys: Vec<f64> = ts
        .iter()
        .enumerate()
        .map(|(i, t)| 3.0 * (-t / 1.7).exp() + 0.4 + 0.01 * ((i * 7 % 5) as f64 - 2.0))
        .collect();
    let calls = std::cell::Cell::new(0usize);
    let model = |p: &[f64]| {
        calls.set(calls.get() + 1);
        // p[3] does nothing (zero column); p[4] duplicates the offset p[2] (collinear).
        DVector::from_iterator(
            ts.len(),
            ts.iter()
                .zip(&ys)
                .map(|(t, y)| (p[0] * (-t / p[1]).exp() + p[2] + p[4] + 0.0 * p[3] - y) / 0.01),
        )
    };
    let names: Vec<String> = ["amp", "tau", "offset", "idle", "offset2"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let (p0, opts) = (vec![1.0, 1.0, 0.0, 0.0, 0.0], LsqOptions::default());
    let s = least_squares(model, &p0, &[], &names, &opts).unwrap();
    let fused_calls = calls.replace(0);

    // The same steps, each evaluating what it needs afresh.
    let mut f = model;
    let mut p = p0.clone();
    let mut free: Vec<usize> = (0..p.len()).collect();
    let unobservable = find_unobservable(&mut f, &p, &mut free, &names, &opts);
    let min = minimize(&mut f, &mut p, &free, &opts);
    let j = jacobian(&mut f, &p, &free);
    let reduced = min.cost / (ts.len() - free.len()) as f64;
    let cov = covariance(&j, reduced).unwrap();
    let stepwise_calls = calls.get();

    assert_eq!(s.unobservable, unobservable);
    assert_eq!(s.free, free);
    assert_eq!(s.free, vec![0, 1, 2]);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&s.params), bits(&p));
    assert_eq!(s.chi2.to_bits(), min.cost.to_bits());
    assert_eq!(s.iterations, min.iterations);
    for (c, &i) in free.iter().enumerate() {
        assert_eq!(
            s.std_errors[i].map(f64::to_bits),
            Some(cov[(c, c)].max(0.0).sqrt().to_bits())
        );
    }
    // The amplitude and time constant found (the fit is not vacuous).
    assert!((s.params[0] - 3.0).abs() < 0.05, "{:?}", s.params);
    assert!((s.params[1] - 1.7).abs() < 0.05, "{:?}", s.params);
    assert!(
        fused_calls < stepwise_calls,
        "{fused_calls} vs {stepwise_calls} evaluations"
    );
}
