//! One number format for every report page and text summary, so a table never shows `0.0020`
//! beside `5.284e-4` or `p 0.0000`: four decimals in [0.1, 1e5), scientific with four
//! significant digits otherwise, and p-values with two significant digits down to `< 1e-4`.

/// A number: four decimals in [0.1, 1e5) (and for 0), `1.234e-3` otherwise, a dash if not
/// finite.
pub fn number(v: f64) -> String {
    if !v.is_finite() {
        "\u{2013}".into()
    } else if v == 0.0 || (0.1..1e5).contains(&v.abs()) {
        format!("{v:.4}")
    } else {
        format!("{v:.3e}")
    }
}

/// A p-value: `< 1e-4` below 1e-4, two significant digits otherwise (`0.38`, `0.038`,
/// `3.8e-4`), a dash if not finite.
pub fn p_value(p: f64) -> String {
    if !p.is_finite() {
        "\u{2013}".into()
    } else if p < 1e-4 {
        "< 1e-4".into()
    } else if p < 0.01 {
        format!("{p:.1e}")
    } else if p < 0.1 {
        format!("{p:.3}")
    } else {
        format!("{p:.2}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_format() {
        assert_eq!(number(0.002), "2.000e-3");
        assert_eq!(number(5.284e-4), "5.284e-4");
        assert_eq!(number(0.5), "0.5000");
        assert_eq!(number(-12.0), "-12.0000");
        assert_eq!(number(0.0), "0.0000");
        assert_eq!(number(f64::NAN), "\u{2013}");
        assert_eq!(p_value(0.0), "< 1e-4");
        assert_eq!(p_value(3.8e-4), "3.8e-4");
        assert_eq!(p_value(0.0381), "0.038");
        assert_eq!(p_value(0.133), "0.13");
        assert_eq!(p_value(1.0), "1.00");
    }
}
