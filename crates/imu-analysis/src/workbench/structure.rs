//! What remains in the residuals: explanatory signals, their correlation with the residuals, the
//! lag-1 autocorrelation and periodic components in the static segments.

use super::*;

/// Explanatory signals per observation: (name, values).
pub(super) fn signals(points: &[FitPoint], triad: Triad) -> Vec<(String, Vec<f64>)> {
    let u = triad.unit();
    let mut out: Vec<(String, Vec<f64>)> = Vec::new();
    let col = |f: &dyn Fn(&FitPoint) -> f64| points.iter().map(f).collect::<Vec<f64>>();
    for (a, name) in AXES.iter().enumerate() {
        out.push((format!("input {name} [{u}]"), col(&|p| p.true_input[a])));
    }
    out.push((
        format!("input magnitude [{u}]"),
        col(&|p| p.true_input.norm()),
    ));
    for (a, name) in AXES.iter().enumerate() {
        out.push((
            format!("sign of input {name}"),
            col(&|p| p.true_input[a].signum()),
        ));
    }
    for (a, name) in AXES.iter().enumerate() {
        out.push((
            format!("specific force {name} [m/s^2]"),
            col(&|p| p.conditions.specific_force_m_s2[a]),
        ));
    }
    out.push(("temperature [degC]".into(), col(&|p| p.conditions.temp_c)));
    out.push((
        "time since power-on [s]".into(),
        col(&|p| p.conditions.time_since_power_on_s),
    ));
    for (a, name) in AXES.iter().enumerate() {
        out.push((
            format!("rotation rate {name} [rad/s]"),
            col(&|p| p.conditions.angular_rate_rad_s[a]),
        ));
    }
    out.push((
        "rotation rate squared [rad^2/s^2]".into(),
        col(&|p| p.conditions.angular_rate_rad_s.norm_squared()),
    ));
    // Table angle: direction of the specific force in the plane normal to the sensor axis it
    // varies least along.
    let f: Vec<_> = points
        .iter()
        .map(|p| p.conditions.specific_force_m_s2.normalize())
        .collect();
    if f.iter().all(|v| v.iter().all(|x| x.is_finite())) && !f.is_empty() {
        let var = |a: usize| {
            let m = f.iter().map(|v| v[a]).sum::<f64>() / f.len() as f64;
            f.iter().map(|v| (v[a] - m).powi(2)).sum::<f64>()
        };
        let axis = (0..3)
            .min_by(|&a, &b| var(a).total_cmp(&var(b)))
            .unwrap_or(0);
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        out.push((
            format!("table angle about {} [deg]", AXES[axis]),
            f.iter().map(|v| v[j].atan2(v[i]).to_degrees()).collect(),
        ));
    }
    out
}

pub(super) fn residual_structure(
    segs: &[SegmentResidual],
    signals: &[(String, Vec<f64>)],
    a: usize,
) -> Structure {
    let r: Vec<f64> = segs.iter().map(|s| s.residual[a]).collect();
    let mut correlates: Vec<Correlate> = signals
        .iter()
        .map(|(name, v)| Correlate {
            signal: name.clone(),
            r: descriptive::correlation(&r, v).unwrap_or(0.0),
        })
        .filter(|c| c.r.is_finite() && c.r != 0.0)
        .collect();
    correlates.sort_by(|x, y| y.r.abs().total_cmp(&x.r.abs()));
    let mut order: Vec<usize> = (0..segs.len()).collect();
    order.sort_by(|&i, &j| segs[i].start_s.total_cmp(&segs[j].start_s));
    let z: Vec<f64> = order.iter().map(|&i| segs[i].z[a]).collect();
    let t: Vec<f64> = order
        .iter()
        .map(|&i| 0.5 * (segs[i].start_s + segs[i].end_s))
        .collect();
    Structure {
        correlates,
        lag1_autocorrelation: descriptive::lag1_autocorrelation(&z),
        dominant_period_s: lomb_scargle_peak(&t, &z),
    }
}

/// Periodic components inside the static segments: the averaged, Hann-windowed periodogram of
/// blocks of every static segment, each bin compared with the median of its neighbourhood; a
/// bin standing out at a false-alarm probability of 1e-6 over all bins is a line.
pub fn spectral_lines(series: &ImuSeries, obs: &Observations, triad: Triad) -> Vec<SpectralLine> {
    let data = if triad == Triad::Gyro {
        &series.gyro_rad_s
    } else {
        &series.accel_m_s2
    };
    let statics: Vec<_> = obs.segmentation.of_kind(SegmentKind::Static).collect();
    let Some(shortest) = statics.iter().map(|s| s.n).min() else {
        return Vec::new();
    };
    // The data rate from the static segments' spans (intervals over time), not the median
    // interval: stamps quantized to device ticks coarser than the sample interval (a 100 Hz
    // stream on 6.5536 ms ticks) have a median interval of two ticks, which would put every
    // line at 0.76 of its frequency.
    let (intervals, span_s) = statics.iter().fold((0usize, 0.0), |(n, span), seg| {
        let r = seg.range();
        let t = &series.t_s[r];
        match (t.first(), t.last()) {
            (Some(a), Some(b)) if t.len() > 1 => (n + t.len() - 1, span + (b - a)),
            _ => (n, span),
        }
    });
    let rate = if span_s > 0.0 {
        intervals as f64 / span_s
    } else {
        series.sample_rate_hz()
    };
    let mut len = 1usize;
    while len * 2 <= shortest.min(1024) {
        len *= 2;
    }
    if len < 64 {
        return Vec::new();
    }
    let mut out = Vec::new();
    for axis in 0..3 {
        let mut periodogram = Periodogram::new(len);
        for s in &statics {
            let y: Vec<f64> = data[s.range()].iter().map(|v| v[axis]).collect();
            periodogram.add_blocks(&y);
        }
        if periodogram.blocks() < 4 {
            continue;
        }
        out.extend(
            periodogram
                .lines(1e-6)
                .into_iter()
                .map(|peak| SpectralLine {
                    axis,
                    frequency_hz: peak.bin as f64 * rate / len as f64,
                    amplitude: peak.amplitude,
                    ratio: peak.ratio,
                }),
        );
    }
    out
}
