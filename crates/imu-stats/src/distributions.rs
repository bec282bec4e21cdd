//! Distribution functions for the significance tests and confidence intervals: survival
//! functions of the chi-square, F and Student t distributions, the normal and chi-square
//! quantiles and the two-sided Student t critical value, all from `statrs` (regularized
//! incomplete gamma and beta functions, exact inverses) rather than hand-written special
//! functions.

use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor, Normal, StudentsT};

/// Probability that a chi-square variable with `dof` degrees of freedom exceeds `chi2`
/// (NaN for `dof <= 0`).
pub fn chi2_sf(chi2: f64, dof: f64) -> f64 {
    match ChiSquared::new(dof) {
        Ok(d) if dof > 0.0 => d.sf(chi2.max(0.0)).clamp(0.0, 1.0),
        _ => f64::NAN,
    }
}

/// Probability that an F(d1, d2) variable exceeds `f` (NaN for non-positive degrees of
/// freedom).
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if !(d1 > 0.0 && d2 > 0.0) {
        return f64::NAN;
    }
    if f <= 0.0 {
        return 1.0;
    }
    match FisherSnedecor::new(d1, d2) {
        Ok(d) => d.sf(f).clamp(0.0, 1.0),
        Err(_) => f64::NAN,
    }
}

/// Two-sided p-value of a Student t statistic with `dof` degrees of freedom (1 for NaN, 0 for
/// an infinite statistic).
pub fn student_t_two_sided_p(t: f64, dof: f64) -> f64 {
    if !t.is_finite() {
        return if t.is_nan() { 1.0 } else { 0.0 };
    }
    match StudentsT::new(0.0, 1.0, dof) {
        Ok(d) => (2.0 * d.sf(t.abs())).clamp(0.0, 1.0),
        Err(_) => f64::NAN,
    }
}

/// The two-sided Student t critical value: `|T| > t` with probability `p` for `dof` degrees of
/// freedom (e.g. 2.228 for `p = 0.05`, `dof = 10`); NaN for `dof <= 0` or `p` outside (0, 1).
pub fn student_t_two_sided_quantile(p: f64, dof: f64) -> f64 {
    if !(p > 0.0 && p < 1.0) {
        return f64::NAN;
    }
    match StudentsT::new(0.0, 1.0, dof) {
        Ok(d) if dof > 0.0 => d.inverse_cdf(1.0 - 0.5 * p),
        _ => f64::NAN,
    }
}

/// Standard normal quantile at probability `p` (clamped into the open unit interval).
pub fn normal_quantile(p: f64) -> f64 {
    let std_normal = Normal::standard();
    std_normal.inverse_cdf(p.clamp(1e-300, 1.0 - 1e-16))
}

/// Chi-square quantile with `nu` degrees of freedom at probability `p`.
pub fn chi2_quantile(p: f64, nu: f64) -> f64 {
    match ChiSquared::new(nu) {
        Ok(d) => d.inverse_cdf(p.clamp(0.0, 1.0)).max(1e-12 * nu),
        Err(_) => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_survival_matches_tables() {
        // Reference values: scipy.stats.chi2.sf.
        let cases = [
            (3.841_458_820_694_124, 1.0, 0.05),
            (10.827_566_170_662_733, 1.0, 0.001),
            (18.307_038_053_275_146, 10.0, 0.05),
            (29.588_298_445_074_4, 10.0, 0.001),
            (124.342_113_404_246_9, 100.0, 0.049_999_999_998_467_42),
            (2.0, 2.0, (-1.0f64).exp()),
        ];
        for (x, k, p) in cases {
            let got = chi2_sf(x, k);
            assert!(
                (got - p).abs() < 1e-9 * p.max(1e-3),
                "chi2_sf({x}, {k}) = {got}, want {p}"
            );
        }
        assert!(chi2_sf(1.0, 0.0).is_nan());
    }

    #[test]
    fn f_survival_matches_tables() {
        // Reference values: scipy.stats.f.sf.
        let cases = [
            (4.964_602_743_730_711, 1.0, 10.0, 0.05),
            (3.325_834_530_413_011, 5.0, 10.0, 0.05),
            (
                10.481_170_611_434_99,
                5.0,
                10.0,
                0.000_999_828_763_386_346_5,
            ),
            (1.0, 3.0, 60.0, 0.399_157_612_179_468_77),
        ];
        for (f, d1, d2, p) in cases {
            let got = f_sf(f, d1, d2);
            assert!(
                (got - p).abs() < 1e-8 * p.max(1e-3),
                "f_sf({f}, {d1}, {d2}) = {got}, want {p}"
            );
        }
        assert!((student_t_two_sided_p(2.228_138_851_986_274, 10.0) - 0.05).abs() < 1e-9);
        // F(1, d) is t^2: P(F > t^2) = 2 P(T > t); large d approaches the normal 1.96.
        assert!((f_sf(1.96f64.powi(2), 1.0, 1e6) - 0.05).abs() < 1e-4);
    }

    #[test]
    fn quantiles_invert_the_distributions() {
        // scipy.stats.norm.ppf(0.975), chi2.ppf(0.025, 10), chi2.ppf(0.975, 10).
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-9);
        assert!((chi2_quantile(0.025, 10.0) - 3.246_972_780_236_841_4).abs() < 1e-8);
        assert!((chi2_quantile(0.975, 10.0) - 20.483_177_350_807_39).abs() < 1e-8);
        assert!((chi2_sf(chi2_quantile(0.9, 3.5), 3.5) - 0.1).abs() < 1e-10);
        // scipy.stats.t.ppf(0.975, 10), t.ppf(0.995, 4.5); and the inverse of the p-value.
        assert!((student_t_two_sided_quantile(0.05, 10.0) - 2.228_138_851_986_274).abs() < 1e-8);
        assert!((student_t_two_sided_quantile(0.01, 4.5) - 4.272_823_993_011_293).abs() < 1e-6);
        let t = student_t_two_sided_quantile(0.133, 7.3);
        assert!((student_t_two_sided_p(t, 7.3) - 0.133).abs() < 1e-10);
        assert!(student_t_two_sided_quantile(0.0, 5.0).is_nan());
    }
}
