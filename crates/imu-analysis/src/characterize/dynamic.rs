//! Dynamic test of Aslan & Saranli 3.4 (Figures 12-13): integrate the gyro about the rotation
//! axis and compare with the rate table's angle; the angle error grows without bound.
//!
//! Before comparing, the timing offset between the reference and the sensor is found by
//! cross-correlating their rates (sub-sample by parabolic interpolation of the correlation
//! peak) and removed, so a clock offset does not masquerade as an angle error during moves.

use std::path::Path;

use serde::Serialize;

use crate::input::ImuSeries;
use crate::render::svg::{Chart, Figure, Look, Series, SeriesLook, Style};
use imu_stats::descriptive::correlation;
use imu_stats::linear::ordinary_least_squares;

/// Errors of the dynamic analysis.
#[derive(Debug, thiserror::Error)]
pub enum DynamicError {
    /// The reference file could not be read.
    #[error("{path}: cannot read the reference")]
    Io {
        /// The file.
        path: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A reference CSV line is malformed.
    #[error("{path}:{line}: {message} (expected `time_s, angle_deg`)")]
    Csv {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Too little data, or no overlap between reference and sensor.
    #[error("{0}")]
    NoOverlap(String),
}

/// The reference rotation: table angle over time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Reference {
    /// Times on the reference clock, s (increasing).
    pub t_s: Vec<f64>,
    /// Table angle, rad.
    pub angle_rad: Vec<f64>,
    /// Table rate, rad/s, if the reference has it (else differentiated from the angle).
    pub rate_rad_s: Option<Vec<f64>>,
    /// Where it came from.
    pub origin: String,
}

impl Reference {
    /// The table angle and rate recorded in a simulator truth file. The simulator restarts the
    /// table angle at 0 in every segment; the segments are joined here so the angle is
    /// continuous (the table does not jump at a segment boundary).
    pub fn from_truth(truth: &imu_rec::truth::Truth, origin: &str) -> Self {
        let mut angle_rad = Vec::with_capacity(truth.samples.len());
        let mut offset = 0.0;
        for (i, s) in truth.samples.iter().enumerate() {
            if i > 0 {
                let p = &truth.samples[i - 1];
                if p.segment != s.segment {
                    let expected = angle_rad[i - 1] + s.table_rate_rad_s * (s.t_s - p.t_s);
                    offset = expected - s.table_angle_rad;
                }
            }
            angle_rad.push(s.table_angle_rad + offset);
        }
        Self {
            t_s: truth.samples.iter().map(|s| s.t_s).collect(),
            angle_rad,
            rate_rad_s: Some(truth.samples.iter().map(|s| s.table_rate_rad_s).collect()),
            origin: origin.to_string(),
        }
    }

    /// Reads a CSV of `time_s, angle_deg` (a header line and `#` comments are skipped).
    pub fn read_csv(path: &Path) -> Result<Self, DynamicError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| DynamicError::Io {
            path: p.clone(),
            source,
        })?;
        let mut r = Self {
            origin: p.clone(),
            ..Self::default()
        };
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let f: Vec<&str> = line.split([',', ';', '\t']).map(str::trim).collect();
            let parsed: Option<(f64, f64)> = match f.as_slice() {
                [a, b, ..] => a.parse().ok().zip(b.parse().ok()),
                _ => None,
            };
            match parsed {
                Some((t, a)) => {
                    if let Some(&last) = r.t_s.last()
                        && t <= last
                    {
                        return Err(DynamicError::Csv {
                            path: p,
                            line: i + 1,
                            message: format!("time {t} does not increase"),
                        });
                    }
                    r.t_s.push(t);
                    r.angle_rad.push(f64::to_radians(a));
                }
                None if r.t_s.is_empty() && f[0].parse::<f64>().is_err() => {} // header
                None => {
                    return Err(DynamicError::Csv {
                        path: p,
                        line: i + 1,
                        message: format!("cannot parse `{line}`"),
                    });
                }
            }
        }
        r.angle_rad = unwrap(std::mem::take(&mut r.angle_rad));
        Ok(r)
    }

    fn rates(&self) -> Vec<f64> {
        if let Some(r) = &self.rate_rad_s {
            return r.clone();
        }
        let n = self.t_s.len();
        (0..n)
            .map(|i| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                if b == a {
                    0.0
                } else {
                    (self.angle_rad[b] - self.angle_rad[a]) / (self.t_s[b] - self.t_s[a])
                }
            })
            .collect()
    }
}

/// Settings of the dynamic analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicOptions {
    /// Rotation axis in sensor axes (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Largest timing offset searched, s (either way).
    pub max_offset_s: f64,
    /// Points kept in the reported error curve.
    pub curve_points: usize,
}

impl Default for DynamicOptions {
    fn default() -> Self {
        Self {
            axis: 2,
            max_offset_s: 1.0,
            curve_points: 2000,
        }
    }
}

/// The comparison of one sensor stream with the reference.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DynamicRun {
    /// Input description.
    pub origin: String,
    /// Rotation axis, `x`, `y` or `z`.
    pub axis: String,
    /// Reference clock minus sensor clock for the same event, s: the reference is read at
    /// `t_sensor + reference_delay_s`.
    pub reference_delay_s: f64,
    /// Peak normalised cross-correlation of the rates.
    pub rate_correlation: f64,
    /// -1 when the gyro turns the opposite way to the reference angle (then flipped).
    pub sign: f64,
    /// Compared span, s.
    pub duration_s: f64,
    /// Total reference rotation (sum of |steps|), deg.
    pub reference_travel_deg: f64,
    /// Angle error at the end, deg.
    pub final_error_deg: f64,
    /// Largest |angle error|, deg.
    pub max_abs_error_deg: f64,
    /// RMS angle error, deg.
    pub rms_error_deg: f64,
    /// Slope of a line fitted to the error, deg/s.
    pub growth_deg_s: f64,
    /// Its standard error (white-residual formula: optimistic for drifting errors), deg/s.
    pub growth_std_deg_s: f64,
    /// The slope in deg/h.
    pub growth_deg_h: f64,
    /// `(t_s, error_deg)`, decimated to about `curve_points`.
    pub error_curve: Vec<(f64, f64)>,
    /// `(t_s, gyro angle_deg, reference angle_deg)`, decimated.
    pub angle_curve: Vec<(f64, f64, f64)>,
    /// `(t_s, gyro rate_deg_s, reference rate_deg_s)`, decimated.
    pub rate_curve: Vec<(f64, f64, f64)>,
}

/// Raw and calibrated runs side by side.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DynamicReport {
    /// Reference description.
    pub reference: String,
    /// The uncalibrated stream, if analysed.
    pub raw: Option<DynamicRun>,
    /// The calibrated stream, if analysed.
    pub corrected: Option<DynamicRun>,
    /// |raw growth| / |corrected growth| (how much calibration slows the drift); `None` unless
    /// both streams were analysed and a calibration was loaded.
    pub growth_reduction_factor: Option<f64>,
    /// What the two streams say about the calibration.
    pub calibration: CalibrationEffect,
    /// Plain-language summary.
    pub summary: String,
}

/// What comparing the raw and the calibrated stream says about the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum CalibrationEffect {
    /// Only one stream was analysed.
    NotCompared,
    /// The calibrated stream equals the raw one: no calibration was loaded when the recording
    /// was made, so the comparison says nothing about a calibration.
    NoCalibrationLoaded,
    /// A calibration was loaded; |raw growth| / |calibrated growth|.
    Reduces {
        /// The factor.
        factor: f64,
    },
}

/// The calibrated stream is the raw one (to rounding): the largest rate difference over the
/// compared curves is below 1e-9 of the largest rate (or 1e-12 deg/s).
fn same_stream(raw: &DynamicRun, corrected: &DynamicRun) -> bool {
    let scale = raw
        .rate_curve
        .iter()
        .fold(0.0f64, |m, p| m.max(p.1.abs()))
        .max(1e-3);
    raw.rate_curve.len() == corrected.rate_curve.len()
        && raw
            .rate_curve
            .iter()
            .zip(&corrected.rate_curve)
            .all(|(a, b)| (a.1 - b.1).abs() <= 1e-9 * scale)
}

/// Compares raw and/or calibrated runs.
pub fn compare(
    reference: &Reference,
    raw: Option<DynamicRun>,
    corrected: Option<DynamicRun>,
) -> DynamicReport {
    let calibration = match (&raw, &corrected) {
        (Some(r), Some(c)) if same_stream(r, c) => CalibrationEffect::NoCalibrationLoaded,
        (Some(r), Some(c)) => CalibrationEffect::Reduces {
            factor: r.growth_deg_s.abs() / c.growth_deg_s.abs(),
        },
        _ => CalibrationEffect::NotCompared,
    };
    let growth_reduction_factor = match calibration {
        CalibrationEffect::Reduces { factor } => Some(factor),
        _ => None,
    };
    let mut summary = String::new();
    for (name, run) in [("raw", &raw), ("calibrated", &corrected)] {
        if let Some(r) = run {
            summary.push_str(&format!(
                "{name}: error grows {:.4} deg/s ({:.1} deg/h), {:.2} deg after {:.0} s; ",
                r.growth_deg_s, r.growth_deg_h, r.final_error_deg, r.duration_s
            ));
        }
    }
    match calibration {
        CalibrationEffect::Reduces { factor } => {
            summary.push_str(&format!("calibration reduces the growth {factor:.1}x; "))
        }
        CalibrationEffect::NoCalibrationLoaded => summary.push_str(
            "no calibration was loaded when this was recorded (the calibrated stream equals \
             the raw one), so this says nothing about a calibration: record with one loaded \
             (imud --calibration FILE) to see its effect on the drift; ",
        ),
        CalibrationEffect::NotCompared => {}
    }
    if let Some(r) = raw.as_ref().or(corrected.as_ref()) {
        summary.push_str(&format!(
            "timing offset (reference - sensor) {:.1} ms, removed before comparing.",
            r.reference_delay_s * 1e3
        ));
    }
    DynamicReport {
        reference: reference.origin.clone(),
        raw,
        corrected,
        growth_reduction_factor,
        calibration,
        summary,
    }
}

/// Removes full-turn jumps (table angles are often reported modulo 360 deg). Assumes the
/// reference is sampled fast enough that it turns less than half a turn between samples.
fn unwrap(mut angle_rad: Vec<f64>) -> Vec<f64> {
    let tau = std::f64::consts::TAU;
    let mut offset = 0.0;
    for i in 1..angle_rad.len() {
        let raw_prev = angle_rad[i - 1] - offset;
        let d = angle_rad[i] - raw_prev;
        offset += -tau * (d / tau).round();
        angle_rad[i] += offset;
    }
    angle_rad
}

fn interp(t: &[f64], v: &[f64], x: f64) -> f64 {
    let i = t.partition_point(|&a| a <= x);
    if i == 0 {
        return v[0];
    }
    if i == t.len() {
        return v[t.len() - 1];
    }
    let (t0, t1) = (t[i - 1], t[i]);
    v[i - 1] + (v[i] - v[i - 1]) * (x - t0) / (t1 - t0)
}

/// Finds the reference delay (s) that best aligns the reference rate with `rate` sampled at
/// `t`, the peak correlation, and its sign.
pub fn estimate_delay(
    t_s: &[f64],
    rate: &[f64],
    reference: &Reference,
    max_offset_s: f64,
) -> Option<(f64, f64)> {
    let n = t_s.len();
    if n < 10 || reference.t_s.len() < 2 {
        return None;
    }
    let dt = (t_s[n - 1] - t_s[0]) / (n - 1) as f64;
    // Uniform grid over the sensor span; the reference is resampled at shifted grid times.
    let m = ((t_s[n - 1] - t_s[0]) / dt).floor() as usize + 1;
    let grid: Vec<f64> = (0..m).map(|k| t_s[0] + k as f64 * dt).collect();
    let s: Vec<f64> = grid.iter().map(|&g| interp(t_s, rate, g)).collect();
    let ref_rate = reference.rates();
    let kmax = (max_offset_s / dt).ceil() as i64;
    let (r_lo, r_hi) = (reference.t_s[0], reference.t_s[reference.t_s.len() - 1]);
    let corr_at = |k: i64| -> f64 {
        let lag = k as f64 * dt;
        let (mut a, mut b) = (Vec::with_capacity(m), Vec::with_capacity(m));
        for (g, sv) in grid.iter().zip(&s) {
            let x = g + lag;
            if x >= r_lo && x <= r_hi {
                a.push(*sv);
                b.push(interp(&reference.t_s, &ref_rate, x));
            }
        }
        if a.len() < 10 {
            return f64::NAN;
        }
        correlation(&a, &b).unwrap_or(f64::NAN)
    };
    let cs: Vec<(i64, f64)> = (-kmax..=kmax).map(|k| (k, corr_at(k))).collect();
    let &(kbest, cbest) = cs
        .iter()
        .filter(|c| c.1.is_finite())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
    let sign = cbest.signum();
    let at = |k: i64| cs.iter().find(|c| c.0 == k).map(|c| c.1 * sign);
    let frac = match (at(kbest - 1), at(kbest + 1)) {
        (Some(l), Some(r)) if l.is_finite() && r.is_finite() => {
            let c = cbest * sign;
            let den = l - 2.0 * c + r;
            if den < 0.0 {
                (0.5 * (l - r) / den).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        }
        _ => 0.0,
    };
    Some(((kbest as f64 + frac) * dt, cbest))
}

/// Integrates the gyro about `options.axis` and compares with the reference angle.
pub fn analyze(
    series: &ImuSeries,
    reference: &Reference,
    options: &DynamicOptions,
) -> Result<DynamicRun, DynamicError> {
    let n = series.len();
    if n < 10 || reference.t_s.len() < 2 {
        return Err(DynamicError::NoOverlap(format!(
            "{}: too few samples ({n} sensor, {} reference)",
            series.origin,
            reference.t_s.len()
        )));
    }
    let ax = options.axis.min(2);
    let rate: Vec<f64> = series.gyro_rad_s.iter().map(|g| g[ax]).collect();
    let (delay, corr) = estimate_delay(&series.t_s, &rate, reference, options.max_offset_s)
        .ok_or_else(|| {
            DynamicError::NoOverlap(format!(
                "{} and {}: the reference does not overlap the recording (within +/-{} s)",
                series.origin, reference.origin, options.max_offset_s
            ))
        })?;
    let sign = if corr < 0.0 { -1.0 } else { 1.0 };
    let (i0, i1) = overlap(series, reference, delay)?;
    let al = Aligned {
        series,
        rate: &rate,
        reference,
        delay,
        sign,
        i0,
        i1,
    };
    let run = al.integrate();
    let (growth_deg_s, growth_std_deg_s) = error_growth(series, &run.t, &run.err_deg)?;
    let (t, err_deg, ref_deg) = (&run.t, &run.err_deg, &run.ref_deg);
    let travel: f64 = ref_deg.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
    let step = (t.len() / options.curve_points.max(1)).max(1);
    let error_curve = (0..t.len())
        .step_by(step)
        .map(|k| (t[k], err_deg[k]))
        .collect();
    let angle_curve = (0..t.len())
        .step_by(step)
        .map(|k| (t[k], run.gyro_deg[k], ref_deg[k]))
        .collect();
    let rate_curve = al.rate_curve(step);
    let final_error_deg = *err_deg.last().unwrap_or(&f64::NAN);
    Ok(DynamicRun {
        origin: series.origin.clone(),
        axis: ["x", "y", "z"][ax].into(),
        reference_delay_s: delay,
        rate_correlation: corr.abs(),
        sign,
        duration_s: t[t.len() - 1] - t[0],
        reference_travel_deg: travel,
        final_error_deg,
        max_abs_error_deg: err_deg.iter().fold(0.0, |a, e| a.max(e.abs())),
        rms_error_deg: (err_deg.iter().map(|e| e * e).sum::<f64>() / err_deg.len() as f64).sqrt(),
        growth_deg_s,
        growth_std_deg_s,
        growth_deg_h: growth_deg_s * 3600.0,
        error_curve,
        angle_curve,
        rate_curve,
    })
}

/// The first and last sample whose time, shifted by `delay`, is within the reference.
fn overlap(
    series: &ImuSeries,
    reference: &Reference,
    delay: f64,
) -> Result<(usize, usize), DynamicError> {
    let (r_lo, r_hi) = (reference.t_s[0], *reference.t_s.last().unwrap_or(&0.0));
    let idx: Vec<usize> = (0..series.len())
        .filter(|&i| {
            let x = series.t_s[i] + delay;
            x >= r_lo && x <= r_hi
        })
        .collect();
    if idx.len() < 10 {
        return Err(DynamicError::NoOverlap(format!(
            "{} and {}: under 10 samples overlap after aligning the clocks",
            series.origin, reference.origin
        )));
    }
    Ok((idx[0], idx[idx.len() - 1]))
}

/// The recording's rate about the axis aligned with the reference: delayed by `delay` s, signed
/// by `sign`, over samples `i0..=i1`.
struct Aligned<'a> {
    series: &'a ImuSeries,
    rate: &'a [f64],
    reference: &'a Reference,
    delay: f64,
    sign: f64,
    i0: usize,
    i1: usize,
}

/// The integrated gyro angle, the reference angle and their difference per sample, deg.
struct Integrated {
    t: Vec<f64>,
    gyro_deg: Vec<f64>,
    ref_deg: Vec<f64>,
    err_deg: Vec<f64>,
}

impl Aligned<'_> {
    /// The gyro integrated by the trapezoid rule from the first overlapping sample, against
    /// the reference angle from there.
    fn integrate(&self) -> Integrated {
        let (series, reference, rate, delay) = (self.series, self.reference, self.rate, self.delay);
        let (i0, i1) = (self.i0, self.i1);
        let mut angle = 0.0;
        let ref0 = interp(&reference.t_s, &reference.angle_rad, series.t_s[i0] + delay);
        let mut t = Vec::with_capacity(i1 - i0 + 1);
        let mut err_deg = Vec::with_capacity(i1 - i0 + 1);
        let mut gyro_deg = Vec::with_capacity(i1 - i0 + 1);
        let mut ref_deg = Vec::with_capacity(i1 - i0 + 1);
        for i in i0..=i1 {
            if i > i0 {
                angle += 0.5 * (rate[i] + rate[i - 1]) * (series.t_s[i] - series.t_s[i - 1]);
            }
            let r = self.sign
                * (interp(&reference.t_s, &reference.angle_rad, series.t_s[i] + delay) - ref0);
            t.push(series.t_s[i]);
            gyro_deg.push(angle.to_degrees());
            ref_deg.push(r.to_degrees());
            err_deg.push((angle - r).to_degrees());
        }
        Integrated {
            t,
            gyro_deg,
            ref_deg,
            err_deg,
        }
    }

    /// (time, gyro rate, reference rate), deg/s, every `step`-th sample.
    fn rate_curve(&self, step: usize) -> Vec<(f64, f64, f64)> {
        let ref_rates = self.reference.rates();
        (self.i0..=self.i1)
            .step_by(step)
            .map(|i| {
                let x = self.series.t_s[i] + self.delay;
                (
                    self.series.t_s[i],
                    self.rate[i].to_degrees(),
                    self.sign * interp(&self.reference.t_s, &ref_rates, x).to_degrees(),
                )
            })
            .collect()
    }
}

/// The angle error's growth, deg/s, and its standard error: a line fitted to `err_deg` over `t`.
fn error_growth(
    series: &ImuSeries,
    t: &[f64],
    err_deg: &[f64],
) -> Result<(f64, f64), DynamicError> {
    let rows: Vec<Vec<f64>> = t.iter().map(|&x| vec![1.0, x - t[0]]).collect();
    let (c, cov) = ordinary_least_squares(&rows, err_deg).ok_or_else(|| {
        DynamicError::NoOverlap(format!("{}: degenerate time span", series.origin))
    })?;
    let rss: f64 = rows
        .iter()
        .zip(err_deg)
        .map(|(r, e)| (e - c[0] - c[1] * r[1]).powi(2))
        .sum();
    let s2 = rss / (rows.len() as f64 - 2.0).max(1.0);
    Ok((c[1], (cov[(1, 1)] * s2).sqrt()))
}

/// Charts like the paper's Figures 12-13 (rate and angle versus the reference) and the angle
/// error over time for every run. The same colour for the same stream on every chart; the
/// calibrated stream is drawn solid under the raw one, which is dashed, so neither hides the
/// other where they agree.
pub fn charts(report: &DynamicReport) -> Vec<Figure> {
    let mut out = Vec::new();
    // Calibrated first (underneath), raw last (on top, dashed).
    let runs: Vec<(&str, &DynamicRun)> = [("calibrated", &report.corrected), ("raw", &report.raw)]
        .into_iter()
        .filter_map(|(n, r)| r.as_ref().map(|r| (n, r)))
        .collect();
    let look_of = |name: &str| SeriesLook {
        colour: Some(if name == "raw" { 3 } else { 1 }),
        dashed: name == "raw",
    };
    let reference_look = SeriesLook {
        colour: Some(0),
        dashed: false,
    };
    if let Some((_, first)) = runs.first() {
        type Pick = fn(&(f64, f64, f64)) -> f64;
        for (what, quantity, unit, curve) in [
            (
                "Turn rate",
                "rate",
                "deg/s",
                (|r: &DynamicRun| &r.rate_curve) as fn(&DynamicRun) -> &Vec<(f64, f64, f64)>,
            ),
            ("Angle", "angle", "deg", |r: &DynamicRun| &r.angle_curve),
        ] {
            let pick = |c: &[(f64, f64, f64)], f: Pick| c.iter().map(|p| (p.0, f(p))).collect();
            let mut series = vec![Series {
                name: "table".into(),
                points: pick(curve(first), |p| p.2),
                style: Style::Line,
            }];
            let mut looks = vec![reference_look];
            for (name, r) in &runs {
                series.push(Series {
                    name: format!("gyro {name}"),
                    points: pick(curve(r), |p| p.1),
                    style: Style::Line,
                });
                looks.push(look_of(name));
            }
            out.push(Figure {
                chart: Chart {
                    title: format!("{what} about {}: gyro vs table", first.axis),
                    x_label: "time [s]".into(),
                    y_label: format!("{quantity} [{unit}]"),
                    series,
                    ..Chart::default()
                },
                look: Look {
                    series: looks,
                    ..Look::default()
                },
            });
        }
    }
    out.push(Figure {
        chart: Chart {
            title: "Angle error (integrated gyro - table)".into(),
            x_label: "time [s]".into(),
            y_label: "error [deg]".into(),
            series: runs
                .iter()
                .map(|(name, r)| Series {
                    // Whole deg/h: the legend has room for about 24 characters.
                    name: format!("{name}: {:.0} deg/h", r.growth_deg_h),
                    points: r.error_curve.clone(),
                    style: Style::Line,
                })
                .collect(),
            ..Chart::default()
        },
        look: Look {
            series: runs.iter().map(|(name, _)| look_of(name)).collect(),
            ..Look::default()
        },
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delay_and_growth_on_synthetic_steps() {
        let rate_of = |t: f64| {
            let p = t % 4.0;
            if p < 1.0 {
                (std::f64::consts::PI * p).sin() * 0.5
            } else {
                0.0
            }
        };
        let angle_of = |t: f64| {
            let k = (t / 4.0).floor();
            let p = (t % 4.0).min(1.0);
            k * (1.0 / std::f64::consts::PI)
                + 0.5 * (1.0 - (std::f64::consts::PI * p).cos()) / std::f64::consts::PI
        };
        let delay = 0.023;
        let bias = 1e-3;
        let mut s = ImuSeries::default();
        for k in 0..4000 {
            let t = k as f64 * 0.01;
            s.t_s.push(t);
            s.gyro_rad_s.push([0.0, 0.0, rate_of(t) + bias]);
            s.accel_m_s2.push([0.0; 3]);
        }
        let reference = Reference {
            t_s: (0..8000).map(|k| k as f64 * 0.005 - 1.0).collect(),
            angle_rad: (0..8000)
                .map(|k| angle_of((k as f64 * 0.005 - 1.0 - delay).max(0.0)))
                .collect(),
            rate_rad_s: None,
            origin: "synthetic".into(),
        };
        let r = analyze(&s, &reference, &DynamicOptions::default()).unwrap();
        assert!(
            (r.reference_delay_s - delay).abs() < 2e-3,
            "{}",
            r.reference_delay_s
        );
        assert!((r.growth_deg_s - bias.to_degrees()).abs() < 0.02 * bias.to_degrees());
    }
}
