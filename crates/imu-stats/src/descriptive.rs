//! Descriptive statistics shared by every analysis: mean, sample standard deviation, Pearson
//! correlation and lag-1 autocorrelation. One implementation each; what a degenerate input
//! means (a constant series has no correlation) is the caller's choice through `Option`.

/// Arithmetic mean (NaN when empty).
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Sample standard deviation (NaN with fewer than two values).
pub fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return f64::NAN;
    }
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// Pearson correlation of the pairs `(a_i, b_i)` over the shorter of the two series; `None`
/// with fewer than two pairs or when either side is constant (the correlation is undefined).
pub fn correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len().min(b.len());
    if n < 2 {
        return None;
    }
    let (a, b) = (&a[..n], &b[..n]);
    let (ma, mb) = (mean(a), mean(b));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let (da, db) = (x - ma, y - mb);
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// The weighted mean of the largest group of agreeing 3-vectors: among the points whose norm
/// is at most `max_norm`, the one with the most weight within `radius` of it (ties: the
/// smallest norm) is the centre; returns the weighted mean of the points within `radius` of
/// it. `None` when no point qualifies. This is how a gyro's reading at rest is told from rate
/// plateaus, offline (segmentation) and online (the daemon's still detector) alike.
pub fn largest_agreeing_group(
    points: &[([f64; 3], f64)],
    radius: f64,
    max_norm: f64,
) -> Option<[f64; 3]> {
    let dist = |a: &[f64; 3], b: &[f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let norm = |a: &[f64; 3]| dist(a, &[0.0; 3]);
    let group_weight = |c: &[f64; 3]| {
        points
            .iter()
            .filter(|(p, _)| dist(p, c) <= radius)
            .map(|(_, w)| w)
            .sum::<f64>()
    };
    let centre = points
        .iter()
        .filter(|(p, _)| norm(p) <= max_norm)
        .map(|(p, _)| (group_weight(p), *p))
        .max_by(|a, b| a.0.total_cmp(&b.0).then(norm(&b.1).total_cmp(&norm(&a.1))))?
        .1;
    let (mut sum, mut weight) = ([0.0; 3], 0.0);
    for (p, w) in points.iter().filter(|(p, _)| dist(p, &centre) <= radius) {
        for a in 0..3 {
            sum[a] += p[a] * w;
        }
        weight += w;
    }
    (weight > 0.0).then(|| sum.map(|s| s / weight))
}

/// Lag-1 autocorrelation of a series in its given order (0 for fewer than 3 values or a
/// constant series).
pub fn lag1_autocorrelation(x: &[f64]) -> f64 {
    if x.len() < 3 {
        return 0.0;
    }
    let m = mean(x);
    let var: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
    if var <= 0.0 {
        return 0.0;
    }
    x.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / var
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_agreeing_group_wins_over_faster_or_smaller_ones() {
        let points = [
            ([0.10, 0.0, 0.0], 5.0),
            ([0.11, 0.0, 0.0], 5.0),
            ([0.0, 0.0, 0.0], 3.0),
            ([1.0, 0.0, 0.0], 100.0), // a plateau: beyond max_norm
        ];
        let c = largest_agreeing_group(&points, 0.025, 0.35).unwrap();
        assert!((c[0] - 0.105).abs() < 1e-12, "{c:?}");
        assert!(largest_agreeing_group(&points[3..], 0.025, 0.35).is_none());
    }

    #[test]
    fn correlation_and_autocorrelation() {
        let a = [1.0, 2.0, 3.0, 4.0];
        assert!((correlation(&a, &[2.0, 4.0, 6.0, 8.0]).unwrap() - 1.0).abs() < 1e-12);
        assert!((correlation(&a, &[-1.0, -2.0, -3.0, -4.0]).unwrap() + 1.0).abs() < 1e-12);
        assert_eq!(correlation(&a, &[1.0; 4]), None);
        assert_eq!(correlation(&a[..1], &a[..1]), None);
        let alternating = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0];
        assert!(lag1_autocorrelation(&alternating) < -0.8);
        let smooth: Vec<f64> = (0..50).map(|i| (i as f64 * 0.05).sin()).collect();
        assert!(lag1_autocorrelation(&smooth) > 0.9);
    }

    #[test]
    fn mean_and_standard_deviation() {
        assert_eq!(mean(&[1.0, 2.0, 3.0]), 2.0);
        assert!((std_dev(&[1.0, 2.0, 3.0]) - 1.0).abs() < 1e-15);
        assert!(std_dev(&[1.0]).is_nan());
    }
}
