//! Impact test of Aslan & Saranli 3.3 (Figures 10-11): finds shocks in a recording and measures,
//! per event and axis, the peak response, the cross-axis coupling of accelerometers and gyros,
//! and the settling time, with a summary across events.
//!
//! Detection is orientation-free: the accel magnitude minus its median, against a threshold of
//! `k` robust standard deviations (1.4826 x MAD). Coupling is reported two ways: the ratio of
//! peaks (as read off the paper's figures) and a least-squares slope of each axis's response
//! on the struck axis's response over the event window, which averages the noise out and is
//! what a misalignment (or g-sensitivity) predicts.

use serde::Serialize;

use crate::input::ImuSeries;
use crate::render::svg::{Chart, Figure, Look, Series, Style, axis_colour};
use imu_stats::descriptive::{mean, std_dev};
use imu_stats::linear::ordinary_least_squares;

/// Errors of the impact analysis.
#[derive(Debug, thiserror::Error)]
pub enum ImpactError {
    /// Too few samples to analyse.
    #[error("{origin}: only {n} samples; an impact analysis needs at least {min}")]
    TooShort {
        /// The input.
        origin: String,
        /// Samples present.
        n: usize,
        /// Samples needed.
        min: usize,
    },
}

/// Settings of the impact analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct ImpactOptions {
    /// Detection threshold in robust standard deviations of the accel magnitude.
    pub threshold_sigmas: f64,
    /// Shorter gaps between threshold crossings merge into one event, s.
    pub merge_gap_s: f64,
    /// Window before the event for the pre-event level, s (ending `guard_s` before onset).
    pub pre_s: f64,
    /// Gap between the pre-event window and the onset, s.
    pub guard_s: f64,
    /// Longest response window after the onset, s (cut at the next event's pre-window).
    pub post_s: f64,
    /// Settled = within this many pre-event standard deviations of the pre-event level.
    pub settle_sigmas: f64,
    /// ... for this many consecutive samples.
    pub settle_hold_samples: usize,
}

impl Default for ImpactOptions {
    fn default() -> Self {
        Self {
            threshold_sigmas: 10.0,
            merge_gap_s: 0.1,
            pre_s: 0.3,
            guard_s: 0.05,
            post_s: 0.5,
            settle_sigmas: 3.0,
            settle_hold_samples: 5,
        }
    }
}

/// One detected impact.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImpactEvent {
    /// Onset (first sample over the threshold), s.
    pub t_onset_s: f64,
    /// Index of the struck axis (largest accel response): 0 = x, 1 = y, 2 = z.
    pub struck_axis: usize,
    /// Peak accel response per axis (signed, relative to the pre-event level), m/s^2.
    pub accel_peak_m_s2: [f64; 3],
    /// Peak gyro response per axis (signed, relative to the pre-event level), rad/s.
    pub gyro_peak_rad_s: [f64; 3],
    /// |accel peak| / |struck-axis accel peak| (1 on the struck axis).
    pub accel_peak_ratio: [f64; 3],
    /// |gyro peak| / |struck-axis accel peak|, (rad/s)/(m/s^2).
    pub gyro_peak_ratio_rad_s_per_m_s2: [f64; 3],
    /// Least-squares slope of each accel axis's response on the struck axis's response.
    pub accel_coupling: [f64; 3],
    /// Least-squares slope of each gyro's response on the struck accel's, (rad/s)/(m/s^2).
    pub gyro_coupling_rad_s_per_m_s2: [f64; 3],
    /// Time from onset until the accel axis stays within the settle band, s (NaN: never).
    pub accel_settling_s: [f64; 3],
    /// Same for the gyros, s.
    pub gyro_settling_s: [f64; 3],
}

/// Mean, standard deviation, min and max of a quantity across events.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stats {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation.
    pub std: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
    /// Number of finite values.
    pub n: usize,
}

impl Stats {
    /// Statistics of the finite values in `v`.
    pub fn of(v: impl IntoIterator<Item = f64>) -> Self {
        let v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
        Self {
            mean: mean(&v),
            std: std_dev(&v),
            min: v.iter().cloned().fold(f64::NAN, f64::min),
            max: v.iter().cloned().fold(f64::NAN, f64::max),
            n: v.len(),
        }
    }
}

/// Per-axis statistics across events.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImpactSummary {
    /// Accel peak response, m/s^2.
    pub accel_peak_m_s2: [Stats; 3],
    /// Gyro peak response, rad/s.
    pub gyro_peak_rad_s: [Stats; 3],
    /// Accel peak ratio.
    pub accel_peak_ratio: [Stats; 3],
    /// Gyro peak ratio, (rad/s)/(m/s^2).
    pub gyro_peak_ratio_rad_s_per_m_s2: [Stats; 3],
    /// Per-event accel coupling slope.
    pub accel_coupling: [Stats; 3],
    /// Per-event gyro coupling slope, (rad/s)/(m/s^2).
    pub gyro_coupling_rad_s_per_m_s2: [Stats; 3],
    /// Accel settling time, s.
    pub accel_settling_s: [Stats; 3],
    /// Gyro settling time, s.
    pub gyro_settling_s: [Stats; 3],
}

/// A coupling slope pooled over all events, with its standard error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Pooled {
    /// Slope.
    pub value: f64,
    /// Standard error (from the residual scatter).
    pub std_error: f64,
}

/// The impact analysis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImpactReport {
    /// Input description.
    pub origin: String,
    /// Data rate, Hz.
    pub sample_rate_hz: f64,
    /// Median accel magnitude, m/s^2.
    pub baseline_m_s2: f64,
    /// Detection threshold on |magnitude - median|, m/s^2.
    pub threshold_m_s2: f64,
    /// Most common struck axis (0 = x, 1 = y, 2 = z; None without events).
    pub struck_axis: Option<usize>,
    /// The events.
    pub events: Vec<ImpactEvent>,
    /// Statistics across events.
    pub summary: ImpactSummary,
    /// Accel coupling pooled over all events struck on `struck_axis`.
    pub pooled_accel_coupling: [Pooled; 3],
    /// Gyro coupling pooled over those events, (rad/s)/(m/s^2).
    pub pooled_gyro_coupling_rad_s_per_m_s2: [Pooled; 3],
}

struct Window {
    onset: usize,
    pre: std::ops::Range<usize>,
    resp: std::ops::Range<usize>,
}

/// Finds and measures the impacts in a recording.
pub fn analyze(series: &ImuSeries, options: &ImpactOptions) -> Result<ImpactReport, ImpactError> {
    let n = series.len();
    const MIN: usize = 50;
    if n < MIN {
        return Err(ImpactError::TooShort {
            origin: series.origin.clone(),
            n,
            min: MIN,
        });
    }
    let rate = series.sample_rate_hz();
    let mag: Vec<f64> = series
        .accel_m_s2
        .iter()
        .map(|a| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt())
        .collect();
    let baseline = median(&mag);
    let dev: Vec<f64> = mag.iter().map(|m| (m - baseline).abs()).collect();
    let mad = median(&dev);
    // Quantization can make the MAD zero on a quiet unit; keep a floor.
    let sigma = (1.4826 * mad).max(1e-4);
    let threshold = options.threshold_sigmas * sigma;

    let spans = crossings(&dev, threshold, options, rate);
    let windows = windows(&spans, n, options, rate);
    let mut events = Vec::with_capacity(windows.len());
    for w in &windows {
        events.push(measure(series, w, options));
    }
    let struck_axis = {
        let mut count = [0usize; 3];
        for e in &events {
            count[e.struck_axis] += 1;
        }
        (!events.is_empty()).then(|| (0..3).max_by_key(|&i| count[i]).unwrap_or(2))
    };
    let summary = summarize(&events);
    let (pooled_accel_coupling, pooled_gyro_coupling_rad_s_per_m_s2) =
        pooled(series, &windows, &events, struck_axis.unwrap_or(2));
    Ok(ImpactReport {
        origin: series.origin.clone(),
        sample_rate_hz: rate,
        baseline_m_s2: baseline,
        threshold_m_s2: threshold,
        struck_axis,
        events,
        summary,
        pooled_accel_coupling,
        pooled_gyro_coupling_rad_s_per_m_s2,
    })
}

/// Threshold crossings of the accel magnitude's deviation `dev`, merged into events: (first,
/// last) sample of each.
fn crossings(
    dev: &[f64],
    threshold: f64,
    options: &ImpactOptions,
    rate: f64,
) -> Vec<(usize, usize)> {
    let merge = (options.merge_gap_s * rate).ceil().max(1.0) as usize;
    let mut spans: Vec<(usize, usize)> = Vec::new();
    for (i, d) in dev.iter().enumerate() {
        if *d > threshold {
            match spans.last_mut() {
                Some((_, end)) if i - *end <= merge => *end = i,
                _ => spans.push((i, i)),
            }
        }
    }
    spans
}

/// The pre-impact and response windows of each event in `spans` (of `n` samples), kept clear of
/// the neighbouring events; an event without 3 quiet samples before it is dropped.
fn windows(spans: &[(usize, usize)], n: usize, options: &ImpactOptions, rate: f64) -> Vec<Window> {
    let pre_n = (options.pre_s * rate).round().max(3.0) as usize;
    let guard_n = (options.guard_s * rate).round() as usize;
    let post_n = (options.post_s * rate).round().max(1.0) as usize;
    let mut windows = Vec::new();
    for (k, &(start, _)) in spans.iter().enumerate() {
        let prev_end = if k == 0 { 0 } else { spans[k - 1].1 + 1 };
        let pre_end = start.saturating_sub(guard_n).max(prev_end);
        let pre_start = pre_end.saturating_sub(pre_n).max(prev_end);
        let next_start = spans.get(k + 1).map_or(n, |s| s.0);
        let resp_start = start.saturating_sub(guard_n).max(pre_end);
        let resp_end = (start + post_n)
            .min(next_start.saturating_sub(guard_n + pre_n / 2))
            .max(start + 1)
            .min(n);
        if pre_end - pre_start < 3 {
            continue;
        }
        windows.push(Window {
            onset: start,
            pre: pre_start..pre_end,
            resp: resp_start..resp_end,
        });
    }
    windows
}

/// Per axis statistics of the events' measures.
fn summarize(events: &[ImpactEvent]) -> ImpactSummary {
    let stats = |f: &dyn Fn(&ImpactEvent) -> [f64; 3]| -> [Stats; 3] {
        [0, 1, 2].map(|i| Stats::of(events.iter().map(|e| f(e)[i])))
    };
    ImpactSummary {
        accel_peak_m_s2: stats(&|e| e.accel_peak_m_s2),
        gyro_peak_rad_s: stats(&|e| e.gyro_peak_rad_s),
        accel_peak_ratio: stats(&|e| e.accel_peak_ratio),
        gyro_peak_ratio_rad_s_per_m_s2: stats(&|e| e.gyro_peak_ratio_rad_s_per_m_s2),
        accel_coupling: stats(&|e| e.accel_coupling),
        gyro_coupling_rad_s_per_m_s2: stats(&|e| e.gyro_coupling_rad_s_per_m_s2),
        accel_settling_s: stats(&|e| e.accel_settling_s),
        gyro_settling_s: stats(&|e| e.gyro_settling_s),
    }
}

fn pre_level(v: &[[f64; 3]], r: std::ops::Range<usize>) -> ([f64; 3], [f64; 3]) {
    let mut m = [0.0; 3];
    let mut s = [0.0; 3];
    for i in 0..3 {
        let x: Vec<f64> = v[r.clone()].iter().map(|a| a[i]).collect();
        m[i] = mean(&x);
        s[i] = std_dev(&x);
    }
    (m, s)
}

fn measure(series: &ImuSeries, w: &Window, options: &ImpactOptions) -> ImpactEvent {
    let (am, asd) = pre_level(&series.accel_m_s2, w.pre.clone());
    let (gm, gsd) = pre_level(&series.gyro_rad_s, w.pre.clone());
    let peak = |v: &[[f64; 3]], m: &[f64; 3], i: usize| -> f64 {
        v[w.resp.clone()]
            .iter()
            .map(|a| a[i] - m[i])
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(0.0)
    };
    let accel_peak = [0, 1, 2].map(|i| peak(&series.accel_m_s2, &am, i));
    let gyro_peak = [0, 1, 2].map(|i| peak(&series.gyro_rad_s, &gm, i));
    let struck = (0..3)
        .max_by(|&a, &b| accel_peak[a].abs().total_cmp(&accel_peak[b].abs()))
        .unwrap_or(2);
    let sp = accel_peak[struck].abs();
    let x: Vec<f64> = series.accel_m_s2[w.resp.clone()]
        .iter()
        .map(|a| a[struck] - am[struck])
        .collect();
    let slope = |v: &[[f64; 3]], m: &[f64; 3], i: usize| -> f64 {
        let sxy: f64 = v[w.resp.clone()]
            .iter()
            .zip(&x)
            .map(|(a, x)| (a[i] - m[i]) * x)
            .sum();
        sxy / x.iter().map(|x| x * x).sum::<f64>()
    };
    let t0 = series.t_s[w.onset];
    let settle = |v: &[[f64; 3]], m: &[f64; 3], sd: &[f64; 3], i: usize| -> f64 {
        let band = options.settle_sigmas * sd[i].max(1e-12);
        let mut run = 0;
        for (k, a) in v.iter().enumerate().take(w.resp.end).skip(w.onset) {
            if (a[i] - m[i]).abs() <= band {
                run += 1;
                if run >= options.settle_hold_samples {
                    return series.t_s[k + 1 - run] - t0;
                }
            } else {
                run = 0;
            }
        }
        f64::NAN
    };
    ImpactEvent {
        t_onset_s: t0,
        struck_axis: struck,
        accel_peak_m_s2: accel_peak,
        gyro_peak_rad_s: gyro_peak,
        accel_peak_ratio: accel_peak.map(|p| p.abs() / sp),
        gyro_peak_ratio_rad_s_per_m_s2: gyro_peak.map(|p| p.abs() / sp),
        accel_coupling: [0, 1, 2].map(|i| slope(&series.accel_m_s2, &am, i)),
        gyro_coupling_rad_s_per_m_s2: [0, 1, 2].map(|i| slope(&series.gyro_rad_s, &gm, i)),
        accel_settling_s: [0, 1, 2].map(|i| settle(&series.accel_m_s2, &am, &asd, i)),
        gyro_settling_s: [0, 1, 2].map(|i| settle(&series.gyro_rad_s, &gm, &gsd, i)),
    }
}

/// One regression through the origin over every event window on the struck axis.
fn pooled(
    series: &ImuSeries,
    windows: &[Window],
    events: &[ImpactEvent],
    struck: usize,
) -> ([Pooled; 3], [Pooled; 3]) {
    let mut x = Vec::new();
    let mut ya: [Vec<f64>; 3] = Default::default();
    let mut yg: [Vec<f64>; 3] = Default::default();
    for (w, e) in windows.iter().zip(events) {
        if e.struck_axis != struck {
            continue;
        }
        let (am, _) = pre_level(&series.accel_m_s2, w.pre.clone());
        let (gm, _) = pre_level(&series.gyro_rad_s, w.pre.clone());
        for k in w.resp.clone() {
            x.push(series.accel_m_s2[k][struck] - am[struck]);
            for i in 0..3 {
                ya[i].push(series.accel_m_s2[k][i] - am[i]);
                yg[i].push(series.gyro_rad_s[k][i] - gm[i]);
            }
        }
    }
    let rows: Vec<Vec<f64>> = x.iter().map(|&v| vec![v]).collect();
    let fit = |y: &[f64]| -> Pooled {
        match ordinary_least_squares(&rows, y) {
            Some((c, cov)) if rows.len() > 1 => {
                let rss: f64 = x.iter().zip(y).map(|(x, y)| (y - c[0] * x).powi(2)).sum();
                let s2 = rss / (rows.len() - 1) as f64;
                Pooled {
                    value: c[0],
                    std_error: (cov[(0, 0)] * s2).sqrt(),
                }
            }
            _ => Pooled {
                value: f64::NAN,
                std_error: f64::NAN,
            },
        }
    };
    (
        [0, 1, 2].map(|i| fit(&ya[i])),
        [0, 1, 2].map(|i| fit(&yg[i])),
    )
}

/// Median (NaN when empty).
pub(crate) fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    let mid = s.len() / 2;
    let (_, m, _) = s.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// Charts like the paper's Figures 10-11: every accel axis and every gyro axis (offset by its
/// median) versus time, from a second before the first event to a second after the last.
pub fn charts(series: &ImuSeries, report: &ImpactReport) -> Vec<Figure> {
    let (Some(first), Some(last)) = (report.events.first(), report.events.last()) else {
        return Vec::new();
    };
    let (t_lo, t_hi) = (first.t_onset_s - 1.0, last.t_onset_s + 1.0);
    let lo = series.t_s.partition_point(|&t| t < t_lo);
    let hi = series.t_s.partition_point(|&t| t <= t_hi);
    let mut out = Vec::new();
    for (name, v, unit, scale) in [
        ("accelerometers", &series.accel_m_s2, "m/s^2", 1.0),
        ("gyroscopes", &series.gyro_rad_s, "deg/s", 1f64.to_degrees()),
    ] {
        let s = (0..3)
            .map(|i| {
                let med = median(&v[lo..hi].iter().map(|a| a[i]).collect::<Vec<_>>());
                Series {
                    name: format!("{} - median", ["x", "y", "z"][i]),
                    points: (lo..hi)
                        .map(|k| (series.t_s[k], (v[k][i] - med) * scale))
                        .collect(),
                    style: Style::Line,
                }
            })
            .collect();
        out.push(Figure {
            chart: Chart {
                title: format!("Impacts: {name}, all axes"),
                x_label: "time [s]".into(),
                y_label: format!("output - median [{unit}]"),
                series: s,
                ..Chart::default()
            },
            look: Look {
                series: (0..3).map(axis_colour).collect(),
                ..Look::default()
            },
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn synthetic_shocks_are_found_and_coupled() {
        let n = 3000;
        let mut s = ImuSeries::default();
        for k in 0..n {
            let t = k as f64 * 0.01;
            let noise = ((k * 7919) % 13) as f64 * 1e-3 - 6e-3;
            let phase = t % 1.0;
            let shock = if t > 2.0 && phase < 0.04 {
                40.0 * (std::f64::consts::PI * phase / 0.04).sin()
            } else {
                0.0
            };
            s.t_s.push(t);
            s.accel_m_s2
                .push([0.01 * shock + noise, -noise, 9.8 + shock + noise]);
            s.gyro_rad_s.push([0.0, 0.0, 1e-4 * shock]);
        }
        let r = analyze(&s, &ImpactOptions::default()).unwrap();
        assert_eq!(r.events.len(), 28);
        assert_eq!(r.struck_axis, Some(2));
        assert!((r.pooled_accel_coupling[0].value - 0.01).abs() < 1e-3);
        assert!((r.pooled_gyro_coupling_rad_s_per_m_s2[2].value - 1e-4).abs() < 1e-6);
    }
}
