//! The noise floor a model is held against: the pooled Allan deviation of the static segments
//! (or the sensor's noise tables), the IEEE terms fitted to it, and the floored fit points.

use super::*;

// ------------------------------------------------------------------------------ noise floor

/// The noise floor of one triad: the noise terms per axis and where they came from.
#[derive(Clone, Debug, Serialize)]
pub struct NoiseFloor {
    /// Triad.
    pub triad: Triad,
    /// Where the terms came from.
    pub source: String,
    /// White noise density per axis, U/sqrt(Hz).
    pub white_per_sqrt_hz: [f64; 3],
    /// Bias instability per axis, U (the Allan floor is 0.664 of it).
    pub bias_instability: [f64; 3],
    /// Random walk fitted to the pooled Allan deviation per axis, U sqrt(Hz) (reported; the
    /// floor itself uses the Allan variance at each segment's length).
    pub random_walk_sqrt_hz: [f64; 3],
    /// True where the data do not resolve the random walk (the value is then the fit's, possibly
    /// 0; the candidate tests profile the drift from the residuals instead).
    pub random_walk_unresolved: [bool; 3],
    /// Quantization per axis, U s.
    pub quantization_s: [f64; 3],
    /// Flicker Allan variance floor per axis, U^2 (`(0.664 B)^2`): its long-range correlation
    /// is part of the segment means' covariance.
    pub flicker_var: [f64; 3],
    /// Pooled overlapping Allan deviation of the static segments per axis: (tau s, dev U).
    pub allan: [Vec<(f64, f64)>; 3],
}

impl NoiseFloor {
    /// Variance of the mean of a segment of `duration_s` on `axis`: the Allan variance at the
    /// segment's duration (equal to the variance of the mean for white noise, and the scatter
    /// of adjacent means for coloured noise), read off the pooled curve (log-log
    /// interpolation) or extrapolated beyond its longest tau with the slope of its last
    /// points (clamped between white noise and random walk).
    pub fn segment_mean_variance(&self, axis: usize, duration_s: f64) -> f64 {
        let c = &self.allan[axis];
        let t = duration_s.max(1e-9);
        if c.is_empty() {
            return 0.0;
        }
        let ln = |v: (f64, f64)| (v.0.ln(), v.1.max(1e-300).ln());
        let dev = if t <= c[0].0 {
            c[0].1 * (c[0].0 / t).sqrt()
        } else if let Some(i) = c.iter().position(|p| p.0 >= t) {
            let ((x0, y0), (x1, y1)) = (ln(c[i - 1]), ln(c[i]));
            (y0 + (y1 - y0) * (t.ln() - x0) / (x1 - x0)).exp()
        } else {
            let tail: Vec<(f64, f64)> = c.iter().rev().take(3).map(|p| ln(*p)).collect();
            let slope = if tail.len() < 2 {
                -0.5
            } else {
                let n = tail.len() as f64;
                let mx = tail.iter().map(|p| p.0).sum::<f64>() / n;
                let my = tail.iter().map(|p| p.1).sum::<f64>() / n;
                let sxy: f64 = tail.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
                let sxx: f64 = tail.iter().map(|p| (p.0 - mx).powi(2)).sum();
                (sxy / sxx.max(1e-300)).clamp(-0.5, 0.5)
            };
            let last = c[c.len() - 1];
            last.1 * (t / last.0).powf(slope)
        };
        dev * dev
    }

    /// From a noise characterisation (white density, bias instability, random walk,
    /// quantization step -> Q = lsb / sqrt(12) x sample period); its Allan curve is the
    /// model's, at octave taus from the sample period to a day.
    pub fn from_model(triad: Triad, m: &NoiseModel, rate_hz: f64) -> NoiseFloor {
        let tau0 = 1.0 / rate_hz.max(1e-9);
        let taus: Vec<f64> = (0..)
            .map(|k| tau0 * 2f64.powi(k))
            .take_while(|t| *t < 86_400.0)
            .collect();
        NoiseFloor {
            triad,
            source: "the given noise characterisation".into(),
            white_per_sqrt_hz: m.white_density,
            bias_instability: m.bias_instability,
            random_walk_sqrt_hz: m.random_walk,
            random_walk_unresolved: [false; 3],
            quantization_s: m.quantization_lsb.map(|q| q / 12f64.sqrt() * tau0),
            flicker_var: m
                .bias_instability
                .map(|b| (imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR * b).powi(2)),
            allan: std::array::from_fn(|a| {
                taus.iter().map(|&t| (t, m.allan_deviation(t)[a])).collect()
            }),
        }
    }
}

/// Two candidates whose AIC improvements differ by less than this are not told apart.
pub(super) const AMBIGUOUS_AIC: f64 = 10.0;

/// Shortest static segment used for the noise floor, s.
pub(super) const MIN_NOISE_SEGMENT_S: f64 = 2.0;

/// Measures the noise floor of `triad` from the static segments of `series`: the overlapping
/// Allan variance of each segment at octave taus, pooled over segments by their number of terms,
/// and the IEEE terms fitted to it.
pub fn measure_noise_floor(
    series: &ImuSeries,
    obs: &Observations,
    triad: Triad,
) -> Result<NoiseFloor, DiagnoseError> {
    let rate = series.sample_rate_hz();
    let tau0 = 1.0 / rate;
    let data = if triad == Triad::Gyro {
        &series.gyro_rad_s
    } else {
        &series.accel_m_s2
    };
    let statics: Vec<_> = obs
        .segmentation
        .of_kind(SegmentKind::Static)
        .filter(|s| s.n as f64 * tau0 >= MIN_NOISE_SEGMENT_S)
        .collect();
    if statics.is_empty() {
        return Err(DiagnoseError::NoStaticData {
            triad,
            min_s: MIN_NOISE_SEGMENT_S,
        });
    }
    let total_s: f64 = statics.iter().map(|s| s.n as f64 * tau0).sum();
    let opts = allan::Options {
        taus: TauSet::Octave,
        ..Default::default()
    };
    let mut floor = NoiseFloor {
        triad,
        source: format!(
            "overlapping Allan deviation of {} static segments ({total_s:.0} s in all), IEEE \
             terms fitted",
            statics.len()
        ),
        white_per_sqrt_hz: [0.0; 3],
        bias_instability: [0.0; 3],
        random_walk_sqrt_hz: [0.0; 3],
        random_walk_unresolved: [false; 3],
        quantization_s: [0.0; 3],
        flicker_var: [0.0; 3],
        allan: Default::default(),
    };
    for axis in 0..3 {
        let points = pooled_allan(data, &statics, axis, tau0, &opts);
        floor.allan[axis] = points.iter().map(|p| (p.tau_s, p.dev)).collect();
        let curve = allan::DevCurve {
            kind: Kind::Oadev,
            tau0_s: tau0,
            confidence: 0.683,
            points,
        };
        match noise::fit_terms(&curve) {
            Ok(t) => apply_terms(&mut floor, axis, &t),
            Err(_) => {
                // Too few taus: the segment means' own scatter is all there is.
                floor.white_per_sqrt_hz[axis] = scatter_white_density(data, &statics, axis, tau0);
            }
        }
    }
    Ok(floor)
}

/// The accel and gyro noise floors: the given noise characterisations, else measured from the
/// static segments of `obs`.
pub(super) fn floors(
    series: &ImuSeries,
    obs: &Observations,
    opts: &DiagnoseOptions,
) -> Result<(NoiseFloor, NoiseFloor), DiagnoseError> {
    let rate = series.sample_rate_hz();
    let floor = |t: Triad, given: &Option<NoiseModel>| match given {
        Some(m) => Ok(NoiseFloor::from_model(t, m, rate)),
        None => measure_noise_floor(series, obs, t),
    };
    Ok((
        floor(Triad::Accel, &opts.accel_noise)?,
        floor(Triad::Gyro, &opts.gyro_noise)?,
    ))
}

pub(super) fn apply_terms(floor: &mut NoiseFloor, axis: usize, t: &NoiseTerms) {
    floor.white_per_sqrt_hz[axis] = t.n_u_per_sqrt_hz.value;
    floor.bias_instability[axis] = t.b_u.value;
    floor.flicker_var[axis] =
        (imu_stats::noise_terms::BIAS_INSTABILITY_FACTOR * t.b_u.value).powi(2);
    floor.quantization_s[axis] = t.q_u_s.value;
    // The random walk as fitted; when the segments are too short to resolve it the value is
    // marked as such (the candidate tests profile the drift from the residuals anyway).
    let k = &t.k_u_sqrt_hz;
    floor.random_walk_sqrt_hz[axis] = k.value;
    floor.random_walk_unresolved[axis] = !k.significant;
}

/// The observations of one triad with the noise floor as their standard errors.
/// The observations of one triad with the noise floor's independent part (the Allan variance
/// at the segment's duration less the flicker floor, whose correlation between segments is
/// modelled separately) as their standard errors.
pub(super) fn floored_points(
    points: &[FitPoint],
    floor: &NoiseFloor,
    rate_hz: f64,
    n: &[usize],
) -> Vec<FitPoint> {
    points
        .iter()
        .zip(n)
        .map(|(p, &n)| {
            let duration_s = n as f64 / rate_hz;
            let mut q = p.clone();
            for a in 0..3 {
                let v = floor.segment_mean_variance(a, duration_s);
                let independent = (v - floor.flicker_var[a]).max(0.1 * v);
                q.std_error[a] = independent.sqrt().max(p.std_error[a]);
            }
            q
        })
        .collect()
}

/// The overlapping Allan deviation of `axis` over the static segments `statics` of `data`,
/// pooled per averaging factor by the segments' number of terms (their edf summed), with its
/// 68.3 % confidence interval.
fn pooled_allan(
    data: &[[f64; 3]],
    statics: &[&crate::segment::Segment],
    axis: usize,
    tau0: f64,
    opts: &allan::Options,
) -> Vec<allan::DevPoint> {
    // m -> (sum of var x terms, terms, edf)
    let mut pooled: std::collections::BTreeMap<usize, (f64, f64, f64)> = Default::default();
    for s in statics {
        let y: Vec<f64> = data[s.range()].iter().map(|v| v[axis]).collect();
        let Ok(curve) = allan::deviation(Kind::Oadev, &y, tau0, opts) else {
            continue;
        };
        for p in curve.points {
            let e = pooled.entry(p.m).or_default();
            e.0 += p.dev * p.dev * p.n_terms as f64;
            e.1 += p.n_terms as f64;
            e.2 += p.edf;
        }
    }
    pooled
        .iter()
        .filter(|(_, v)| v.1 > 0.0)
        .map(|(&m, &(sv, n, edf))| {
            let dev = (sv / n).sqrt();
            let (lo, hi) = allan::confidence_interval(dev, edf, 0.683);
            allan::DevPoint {
                m,
                tau_s: m as f64 * tau0,
                dev,
                n_terms: n as usize,
                edf,
                dev_lo: lo,
                dev_hi: hi,
            }
        })
        .collect()
}

/// The white noise density, U/sqrt(Hz), that the scatter of all static samples of `axis` would
/// have as white noise.
fn scatter_white_density(
    data: &[[f64; 3]],
    statics: &[&crate::segment::Segment],
    axis: usize,
    tau0: f64,
) -> f64 {
    let y: Vec<f64> = statics
        .iter()
        .flat_map(|s| data[s.range()].iter().map(|v| v[axis]))
        .collect();
    let m = y.iter().sum::<f64>() / y.len() as f64;
    let var = y.iter().map(|v| (v - m).powi(2)).sum::<f64>() / y.len() as f64;
    (var * tau0).sqrt()
}
