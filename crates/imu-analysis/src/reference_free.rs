//! Reference-free multi-pose calibration: the unit is held still, by hand, in many arbitrary
//! orientations, and turned between them; no index table, no rate table, no truth.
//!
//! * **Accelerometer** (gravity magnitude): at every still pose `k` the corrected specific force
//!   has the magnitude of local gravity, `|accel.inverse(mean_k)| = g`. A weighted
//!   Levenberg-Marquardt fit of the accel model (bias, scale, misalignment and whatever else the
//!   model asks for, e.g. scale nonlinearity) to these residuals gives the parameters; standard
//!   errors come from the covariance scaled by the reduced chi-square, as in `fit.rs`. A
//!   magnitude cannot see a rotation of the whole frame, so that gauge is fixed: the upper
//!   triangle of the misalignment (`xy`, `xz`, `yz`) is held at 0, i.e. the accelerometer axes
//!   DEFINE the body frame (accel x is body x, accel y lies in the body x-y plane). Every other
//!   triad, and any comparison with a truth model, is expressed in that frame
//!   ([`in_accel_frame`]).
//! * **Gyroscope offsets** (bias, and g-sensitivity if the model asks) from the still poses with
//!   the segment fit of `fit.rs`: the true rate there is Earth's rotation, unknown in the sensor
//!   frame without a heading. Its vertical part is known from the latitude (and removed) when
//!   given; the rest (up to 7.3e-5 rad/s) is carried as an extra uncertainty of the bias.
//! * **Gyroscope gains** (scale, misalignment, and any other gain effect of the model) from the
//!   moves: the gyro rate, corrected by the gain model and by the rate measured at the two still
//!   poses around the move (interpolated in time: it removes bias drift, Earth rate and
//!   g-sensitivity to first order), is integrated with a quaternion midpoint rule over the
//!   recording's timestamps; the integrated rotation applied to the previous pose's calibrated
//!   gravity direction must give the next pose's. Each move gives two residuals (the rotation
//!   about gravity is invisible to it); many moves about different axes determine all nine
//!   gains. Fitted by the generic Levenberg-Marquardt of `lsq.rs` with a numeric Jacobian.
//!
//! Timestamps quantised by the device's tick counter (6.55 ms ticks under 10 ms samples) would
//! put sawtooth errors into the integral, so over each move the times are replaced by a
//! straight-line fit of time against sample index (moves with lost samples are skipped). Under
//! the 3DM-GX1's gyro noise the difference is small; on a quieter sensor the raw times leave
//! several times the residual (see the synthetic test).

use imu_model::earth::normal_gravity_m_s2;
use imu_model::nalgebra::{DVector, Matrix3, UnitQuaternion};
use imu_model::units::{EARTH_RATE_RAD_S, STANDARD_GRAVITY_M_S2};
use imu_model::{Calibration, Conditions, EffectKind, Triad, TriadModel, Vec3};

use crate::ImuSeries;
use crate::fit::{FitError, FitOptions, FitPoint, FitResult, Unobservable, fit_triad};
use crate::segment::{Segment, SegmentError, SegmentKind, SegmentOptions, Segmentation};
use imu_stats::lsq::{LsqError, LsqOptions, LsqSolution, least_squares};

/// What to record, in every message about too few or too clustered poses.
pub const POSE_ADVICE: &str = "hold the unit still in 30 or more orientations: each axis up and \
     down, and at 45 degrees in between (resting on an edge, on a corner), turning it about \
     different axes between poses";

/// The procedure, as written into the calibration's provenance.
pub const PROCEDURE: &str = "reference-free multi-pose: accelerometer from the gravity magnitude \
     at still poses, gyro bias from the still poses, gyro gains from the rotations integrated \
     between poses (imu-calibrate --reference-free)";

/// Gyro effects fitted from the integrated rotations (the rest from the still poses).
pub(crate) const GYRO_GAIN_KINDS: [EffectKind; 5] = [
    EffectKind::Misalignment,
    EffectKind::Scale,
    EffectKind::AsymmetricScale,
    EffectKind::TempScale,
    EffectKind::ScaleNonlinearity,
];

/// Accel misalignment entries held at 0 to fix the rotation gauge.
pub(crate) const GAUGE: [&str; 3] = ["misalignment.xy", "misalignment.xz", "misalignment.yz"];

/// Local gravity for a reference-free fit, m/s^2, and the note saying where it came from: the
/// given value, else WGS-84 normal gravity at the latitude, else standard gravity.
pub fn local_gravity(gravity_m_s2: Option<f64>, latitude_deg: Option<f64>) -> (f64, String) {
    match (gravity_m_s2, latitude_deg) {
        (Some(g), _) => (g, format!("local gravity {g:.6} m/s^2 (given)")),
        (None, Some(lat)) => {
            let g = normal_gravity_m_s2(lat, 0.0);
            (
                g,
                format!(
                    "local gravity {g:.6} m/s^2: WGS-84 normal gravity at latitude {lat} deg, \
                     height 0 (about -3.1e-6 m/s^2 per metre above the ellipsoid)"
                ),
            )
        }
        (None, None) => (
            STANDARD_GRAVITY_M_S2,
            format!(
                "local gravity {STANDARD_GRAVITY_M_S2} m/s^2 (standard; give --gravity-m-s2 or \
                 --latitude-deg: gravity varies by 0.5 % over the Earth, and every accel scale \
                 factor absorbs the relative error of g)"
            ),
        ),
    }
}

/// What [`calibrate_reference_free`] fits and how.
#[derive(Clone, Debug)]
pub struct ReferenceFreeOptions {
    /// Accel model to fit (its effects and starting values).
    pub accel: TriadModel,
    /// Gyro model to fit.
    pub gyro: TriadModel,
    /// Local gravity, m/s^2; `None`: WGS-84 normal gravity at `latitude_deg`, else standard
    /// gravity.
    pub gravity_m_s2: Option<f64>,
    /// Geodetic latitude, degrees: the vertical part of Earth's rate (and `g` if not given).
    pub latitude_deg: Option<f64>,
    /// Segmentation settings.
    pub segment: SegmentOptions,
    /// Least-squares settings.
    pub lsq: LsqOptions,
    /// Accel bias wander over the recording (m/s^2), added in quadrature to the bias standard
    /// errors (see [`crate::fit::FitOptions::bias_drift`]).
    pub accel_bias_drift_m_s2: Option<[f64; 3]>,
    /// Gyro bias wander over the recording (rad/s).
    pub gyro_bias_drift_rad_s: Option<[f64; 3]>,
    /// Below this smallest eigenvalue of the normalised normal matrix the poses (or moves) are
    /// too clustered: a warning names the weakest parameter combination and what to record.
    pub weak_eigenvalue: f64,
    /// Parameters held at their start values, as `<triad>.<effect>.<name>` (e.g.
    /// `accel.scale-nonlinearity.cubic.x`): a model choice, e.g. a term known to be absent.
    pub hold: Vec<String>,
}

impl Default for ReferenceFreeOptions {
    /// Accel and gyro: bias + scale + misalignment; standard gravity.
    fn default() -> Self {
        let accel = TriadModel::with_effects(&TriadModel::PAPER_BASE);
        ReferenceFreeOptions {
            gyro: accel.clone(),
            accel,
            gravity_m_s2: None,
            latitude_deg: None,
            segment: SegmentOptions::default(),
            lsq: LsqOptions::default(),
            accel_bias_drift_m_s2: None,
            gyro_bias_drift_rad_s: None,
            weak_eigenvalue: 1e-3,
            hold: Vec::new(),
        }
    }
}

/// The fit of one triad.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TriadFit {
    /// Which triad.
    pub triad: Triad,
    /// The fitted model with standard errors (an effect with a parameter the data could not
    /// determine carries none; gauge-fixed entries carry 0: they are exact by convention).
    #[serde(skip)]
    pub model: TriadModel,
    /// Parameter names, layout of [`TriadModel::params`].
    pub names: Vec<String>,
    /// Parameter units.
    pub units: Vec<String>,
    /// Fitted values.
    pub params: Vec<f64>,
    /// Standard errors; `None` for held parameters.
    pub std_errors: Vec<Option<f64>>,
    /// Indices of the fitted parameters.
    pub free: Vec<usize>,
    /// Correlation matrix of the fitted parameters (order of `free`).
    pub correlation: Vec<Vec<f64>>,
    /// Parameters held at their start values: the gauge, and what the data could not determine.
    pub unobservable: Vec<Unobservable>,
    /// What a residual is.
    pub residual: String,
    /// Its unit.
    pub residual_unit: String,
    /// RMS of the residuals (unweighted).
    pub residual_rms: f64,
    /// Number of residuals.
    pub n_residuals: usize,
    /// Weighted sum of squared residuals.
    pub chi2: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// chi2 / dof (the covariance is scaled by it when above 1).
    pub reduced_chi2: f64,
    /// Smallest eigenvalue of the normalised normal matrix (1 = independent parameters).
    pub min_eigenvalue: f64,
    /// Iterations taken.
    pub iterations: usize,
    /// True if the cost settled within the budget.
    pub converged: bool,
    /// Poor conditioning, held parameters, clustered poses.
    pub warnings: Vec<String>,
}

/// One still pose.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Pose {
    /// Index in `segmentation.segments`.
    pub segment: usize,
    /// Middle of the pose, s (series time).
    pub t_s: f64,
    /// Length, s.
    pub duration_s: f64,
    /// Calibrated specific-force direction (unit vector, body frame; points up).
    pub up: [f64; 3],
    /// `|calibrated specific force| - g` after the fit, m/s^2.
    pub magnitude_error_m_s2: f64,
}

/// One move between consecutive still poses.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Move {
    /// Pose before (index into `poses`).
    pub from_pose: usize,
    /// Pose after.
    pub to_pose: usize,
    /// Integration interval, s.
    pub duration_s: f64,
    /// Angle of the integrated rotation, rad.
    pub angle_rad: f64,
    /// Angle between the predicted and the measured gravity direction after the fit, rad.
    pub error_rad: f64,
    /// Expected noise of that error per component (white gyro noise, pose means), rad.
    pub std_rad: f64,
}

/// Result of [`calibrate_reference_free`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReferenceFreeFit {
    /// The detected segments and thresholds.
    pub segmentation: Segmentation,
    /// Local gravity used, m/s^2.
    pub gravity_m_s2: f64,
    /// The still poses.
    pub poses: Vec<Pose>,
    /// The moves used by the gyro gain fit.
    pub moves: Vec<Move>,
    /// The accel fit (gravity magnitude).
    pub accel: TriadFit,
    /// The gyro fit: offsets from the still poses, gains from the moves (statistics of the
    /// move fit).
    pub gyro: TriadFit,
    /// The gyro offset fit in detail (still-pose means, `fit.rs`).
    pub gyro_static: Option<FitResult>,
    /// The fitted calibration (accel and gyro; provenance procedure set).
    #[serde(skip)]
    pub calibration: Calibration,
    /// Decisions and conventions (gauge, gravity, Earth rate, what was not fitted).
    pub notes: Vec<String>,
}

/// Failures of [`calibrate_reference_free`].
#[derive(Debug, thiserror::Error)]
pub enum ReferenceFreeError {
    /// Segmentation failed.
    #[error(transparent)]
    Segment(#[from] SegmentError),
    /// Too few still poses for the parameters asked for.
    #[error(
        "{found} still pose(s) found, but the reference-free {triad} fit of {n_free} parameters \
         ({what}) needs at least {needed}: {POSE_ADVICE}, still for at least {still_s} s each"
    )]
    TooFewPoses {
        /// Triad whose fit lacks poses.
        triad: Triad,
        /// Still poses found.
        found: usize,
        /// Poses needed.
        needed: usize,
        /// Free parameters.
        n_free: usize,
        /// Which parameters.
        what: String,
        /// Shortest still time that survives segmentation, s.
        still_s: f64,
    },
    /// Too few usable moves for the gyro gains.
    #[error(
        "{found} usable move(s) between still poses (skipped: {skipped}), but the gyro gain fit \
         of {n_free} parameters needs at least {needed}: {POSE_ADVICE}"
    )]
    TooFewMoves {
        /// Usable moves.
        found: usize,
        /// Moves skipped (lost samples).
        skipped: usize,
        /// Moves needed.
        needed: usize,
        /// Free parameters.
        n_free: usize,
    },
    /// The poses cannot separate the primary accel parameters.
    #[error(
        "accel: the poses cannot determine {names}: {reason}; the poses are too clustered: \
         {POSE_ADVICE}"
    )]
    Unobservable {
        /// The parameters.
        names: String,
        /// Why.
        reason: String,
    },
    /// A parameter to hold is not in the model.
    #[error(
        "cannot hold `{0}`: no such parameter in the model (write <triad>.<effect>.<name>, e.g. accel.scale-nonlinearity.cubic.x)"
    )]
    UnknownHold(String),
    /// A least-squares fit failed.
    #[error("{triad}: reference-free fit failed")]
    Lsq {
        /// Triad.
        triad: Triad,
        /// Why.
        #[source]
        source: LsqError,
    },
    /// The gyro offset fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// The fitted model is invalid even with the offending parameter held.
    #[error("the fitted {triad} model is not valid at `{key}`: {message}; fit fewer effects")]
    InvalidModel {
        /// Triad.
        triad: Triad,
        /// Parameter.
        key: String,
        /// Why.
        message: String,
    },
}

/// Mask of the parameters of `names` (one triad) that `opts.hold` names.
fn held(triad: Triad, names: &[String], hold: &[String]) -> Vec<bool> {
    names
        .iter()
        .map(|n| hold.iter().any(|h| *h == format!("{triad}.{n}")))
        .collect()
}

/// Unobservable-list entries for the held parameters of `names`.
fn held_entries(names: &[String], mask: &[bool]) -> Vec<Unobservable> {
    names
        .iter()
        .zip(mask)
        .filter(|(_, h)| **h)
        .map(|(n, _)| Unobservable {
            name: n.clone(),
            reason: "held at its start value (requested)".into(),
        })
        .collect()
}

/// Standard error of a segment mean per axis (floored so a quantised, noiseless axis cannot
/// take all the weight).
pub(crate) fn mean_se(std: [f64; 3], n: usize) -> Vec3 {
    Vec3::from(std.map(|s| (s / (n as f64).sqrt()).max(1e-12)))
}

pub(crate) fn pose_conditions(series: &ImuSeries, seg: &Segment) -> Conditions {
    let mid_s = 0.5 * (seg.start_s + seg.end_s);
    let temp_c = series.temp_at(mid_s);
    Conditions {
        temp_c: if temp_c.is_finite() {
            temp_c
        } else {
            imu_model::units::REFERENCE_TEMP_C
        },
        // The power-on time is unknown: recording time stands in (a warm-up effect would be
        // referred to the recording's start).
        time_since_power_on_s: mid_s,
        specific_force_m_s2: seg.mean_accel(),
        ..Conditions::default()
    }
}

/// Per-effect standard errors into `model`: `None` for an effect with a parameter neither
/// fitted nor gauge-fixed, 0 for gauge-fixed entries.
pub(crate) fn store_std_errors(model: &mut TriadModel, se: &[Option<f64>], gauge: &[usize]) {
    let mut offset = 0;
    for e in model.effects_mut() {
        let n = e.n_params();
        let mine: Option<Vec<f64>> = (offset..offset + n)
            .map(|i| if gauge.contains(&i) { Some(0.0) } else { se[i] })
            .collect();
        e.set_std_errors(mine);
        offset += n;
    }
}

/// Warnings about poorly separated parameters of a solution.
pub(crate) fn conditioning_warnings(
    triad: Triad,
    sol: &LsqSolution,
    names: &[String],
    weak: f64,
    what: &str,
) -> Vec<String> {
    let mut w = Vec::new();
    if sol.min_eigenvalue < weak {
        w.push(format!(
            "{triad}: the {what} barely separate {} (smallest eigenvalue {:.1e} of the normalised \
             normal matrix): {POSE_ADVICE}",
            sol.weakest.join(", "),
            sol.min_eigenvalue
        ));
    }
    for (a, row) in sol.correlation.iter().enumerate() {
        for (b, c) in row.iter().enumerate() {
            if a < b && c.abs() > 0.99 {
                w.push(format!(
                    "{triad}: {} and {} are correlated {c:.3}: poorly separated by these {what}",
                    names[sol.free[a]], names[sol.free[b]]
                ));
            }
        }
    }
    for u in &sol.unobservable {
        w.push(format!("{triad}: {} not fitted: {}", u.name, u.reason));
    }
    if !sol.converged {
        w.push(format!(
            "{triad}: not converged after {} iterations",
            sol.iterations
        ));
    }
    w
}

/// The accel fit from the gravity magnitude at each pose.
struct AccelOutcome {
    fit: TriadFit,
    up: Vec<Vec3>,
    magnitude_error_m_s2: Vec<f64>,
}

fn fit_accel(
    series: &ImuSeries,
    poses: &[&Segment],
    opts: &ReferenceFreeOptions,
    g_m_s2: f64,
    still_s: f64,
) -> Result<AccelOutcome, ReferenceFreeError> {
    let triad = Triad::Accel;
    let mut model = opts.accel.effects_only();
    let names = model.param_names(triad);
    let units = model.param_units(triad);
    let mut p0 = model.params();
    let gauge: Vec<usize> = GAUGE
        .iter()
        .filter_map(|g| names.iter().position(|n| n == g))
        .collect();
    let mut fixed = held(triad, &names, &opts.hold);
    let requested = fixed.clone();
    for &i in &gauge {
        p0[i] = 0.0;
        fixed[i] = true;
    }
    let n_free = fixed.iter().filter(|f| !**f).count();
    if poses.len() <= n_free {
        return Err(ReferenceFreeError::TooFewPoses {
            triad,
            found: poses.len(),
            needed: n_free + 1,
            n_free,
            what: model
                .kinds()
                .iter()
                .map(|k| k.id())
                .collect::<Vec<_>>()
                .join(", "),
            still_s,
        });
    }
    let measured: Vec<Vec3> = poses.iter().map(|s| s.mean_accel()).collect();
    let conditions: Vec<Conditions> = poses.iter().map(|s| pose_conditions(series, s)).collect();
    // The error of |mean| is the mean's error along the gravity direction.
    let sigma_m_s2: Vec<f64> = poses
        .iter()
        .zip(&measured)
        .map(|(s, m)| {
            let u = m.normalize();
            let se = mean_se(s.std_accel_m_s2, s.n);
            (0..3)
                .map(|a| (u[a] * se[a]).powi(2))
                .sum::<f64>()
                .sqrt()
                .max(1e-12)
        })
        .collect();
    let mut work = model.clone();
    let residual = |p: &[f64]| {
        work.set_params(p);
        DVector::from_iterator(
            measured.len(),
            measured
                .iter()
                .zip(&conditions)
                .zip(&sigma_m_s2)
                .map(|((m, c), s)| (work.inverse(*m, c).norm() - g_m_s2) / s),
        )
    };
    let sol =
        least_squares(residual, &p0, &fixed, &names, &opts.lsq).map_err(|source| match source {
            LsqError::TooFewResiduals { n_free, .. } => ReferenceFreeError::TooFewPoses {
                triad,
                found: poses.len(),
                needed: n_free + 1,
                n_free,
                what: "after dropping unobservable parameters".into(),
                still_s,
            },
            source => ReferenceFreeError::Lsq { triad, source },
        })?;
    let primary: Vec<&Unobservable> = sol
        .unobservable
        .iter()
        .filter(|u| {
            ["bias.", "scale.", "misalignment."]
                .iter()
                .any(|p| u.name.starts_with(p))
        })
        .collect();
    if !primary.is_empty() {
        return Err(ReferenceFreeError::Unobservable {
            names: primary
                .iter()
                .map(|u| u.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            reason: primary[0].reason.clone(),
        });
    }

    model.set_params(&sol.params);
    let mut std_errors = sol.std_errors.clone();
    if let Some(drift) = opts.accel_bias_drift_m_s2 {
        for (a, axis) in ["bias.x", "bias.y", "bias.z"].iter().enumerate() {
            if let Some(i) = names.iter().position(|n| n == axis)
                && let Some(se) = std_errors[i].as_mut()
            {
                *se = (*se * *se + drift[a] * drift[a]).sqrt();
            }
        }
    }
    store_std_errors(&mut model, &std_errors, &gauge);

    let corrected: Vec<Vec3> = measured
        .iter()
        .zip(&conditions)
        .map(|(m, c)| model.inverse(*m, c))
        .collect();
    let magnitude_error_m_s2: Vec<f64> = corrected.iter().map(|f| f.norm() - g_m_s2).collect();
    let up: Vec<Vec3> = corrected.iter().map(|f| f.normalize()).collect();
    let n = corrected.len() as f64;
    let rms = (magnitude_error_m_s2.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    // Per axis: the magnitude error as a vector along gravity.
    let mut sq = [0.0; 3];
    for (u, e) in up.iter().zip(&magnitude_error_m_s2) {
        for a in 0..3 {
            sq[a] += (u[a] * e).powi(2) / n;
        }
    }
    model.residual_rms = Some(sq.map(f64::sqrt));

    let mut warnings = conditioning_warnings(triad, &sol, &names, opts.weak_eigenvalue, "poses");
    if poses.len() < 2 * n_free {
        warnings.push(format!(
            "accel: only {} poses for {n_free} parameters: standard errors are rough; {POSE_ADVICE}",
            poses.len()
        ));
    }
    let axis = ["x", "y", "z"];
    for a in 0..3 {
        let hi = up.iter().map(|u| u[a]).fold(f64::NEG_INFINITY, f64::max);
        let lo = up.iter().map(|u| u[a]).fold(f64::INFINITY, f64::min);
        // 0.7 ~ cos 45 degrees.
        if hi < 0.7 || lo > -0.7 {
            warnings.push(format!(
                "accel {}: the axis never pointed within 45 degrees of {} (its gravity component \
                 spans {lo:.2}..{hi:.2} g): {POSE_ADVICE}",
                axis[a],
                if hi < 0.7 && lo > -0.7 {
                    "up or down"
                } else if hi < 0.7 {
                    "up"
                } else {
                    "down"
                },
            ));
        }
    }
    let mut unobservable: Vec<Unobservable> = gauge
        .iter()
        .map(|&i| Unobservable {
            name: names[i].clone(),
            reason: "gauge: the gravity magnitude cannot see a rotation of the whole frame; held \
                     at 0 so that the accelerometer axes define the body frame"
                .into(),
        })
        .collect();
    unobservable.extend(held_entries(&names, &requested));
    unobservable.extend(sol.unobservable.iter().cloned());
    Ok(AccelOutcome {
        fit: TriadFit {
            triad,
            model,
            names,
            units,
            params: sol.params.clone(),
            std_errors,
            free: sol.free.clone(),
            correlation: sol.correlation.clone(),
            unobservable,
            residual: "|corrected specific force| - g at each still pose".into(),
            residual_unit: "m/s^2".into(),
            residual_rms: rms,
            n_residuals: poses.len(),
            chi2: sol.chi2,
            dof: sol.dof,
            reduced_chi2: sol.reduced_chi2,
            min_eigenvalue: sol.min_eigenvalue,
            iterations: sol.iterations,
            converged: sol.converged,
            warnings,
        },
        up,
        magnitude_error_m_s2,
    })
}

/// One move prepared for integration.
#[derive(Clone, Debug)]
pub(crate) struct MoveData {
    from_pose: usize,
    to_pose: usize,
    /// Gyro sample minus the interpolated still-pose rate, rad/s, from the last sample of the
    /// pose before to the first of the pose after.
    rate_rad_s: Vec<Vec3>,
    /// Sample interval from the line fitted to the times, s.
    step_s: f64,
    /// Calibrated up direction at the pose before.
    up_before: Vec3,
    /// Orthonormal basis of the plane normal to the calibrated up direction after.
    e1: Vec3,
    e2: Vec3,
    /// Conditions for the gain model (those of the pose before).
    conditions: Conditions,
    /// Expected noise of each residual component, rad.
    pub(crate) sigma_rad: f64,
}

impl MoveData {
    /// The rotation `sensor_before_from_sensor_after` integrated with the rate corrected by
    /// `gains` (midpoint rule on consecutive samples).
    fn rotation(&self, gains: &TriadModel) -> UnitQuaternion<f64> {
        let mut q = UnitQuaternion::identity();
        let mut w0 = gains.inverse(self.rate_rad_s[0], &self.conditions);
        for r in &self.rate_rad_s[1..] {
            let w1 = gains.inverse(*r, &self.conditions);
            q *= UnitQuaternion::from_scaled_axis((w0 + w1) * (0.5 * self.step_s));
            w0 = w1;
        }
        q
    }

    /// Predicted minus measured up direction after the move, in the plane normal to the
    /// measured one, rad.
    pub(crate) fn residual(&self, gains: &TriadModel) -> [f64; 2] {
        let predicted = self
            .rotation(gains)
            .inverse_transform_vector(&self.up_before);
        [self.e1.dot(&predicted), self.e2.dot(&predicted)]
    }
}

/// Two unit vectors completing `u` to an orthonormal basis.
fn normal_basis(u: Vec3) -> (Vec3, Vec3) {
    let helper = if u.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let e1 = u.cross(&helper).normalize();
    (e1, u.cross(&e1))
}

/// The gyro gain model `gains` fitted to the integrated rotations of `moves` (two whitened
/// residuals per move), with the parameters marked in `fixed` held.
pub(crate) fn fit_gains(
    moves: &[MoveData],
    gains: &TriadModel,
    fixed: &[bool],
    lsq: &LsqOptions,
) -> Result<LsqSolution, LsqError> {
    let mut work = gains.clone();
    let residual = |p: &[f64]| {
        work.set_params(p);
        let mut r = DVector::zeros(2 * moves.len());
        for (k, m) in moves.iter().enumerate() {
            let [a, b] = m.residual(&work);
            r[2 * k] = a / m.sigma_rad;
            r[2 * k + 1] = b / m.sigma_rad;
        }
        r
    };
    let names = gains.param_names(Triad::Gyro);
    least_squares(residual, &gains.params(), fixed, &names, lsq)
}

/// Prepares the moves between consecutive poses; returns them and the number skipped.
pub(crate) fn prepare_moves(
    series: &ImuSeries,
    poses: &[&Segment],
    up: &[Vec3],
    conditions: &[Conditions],
    g_m_s2: f64,
) -> (Vec<MoveData>, usize) {
    let mut out = Vec::new();
    let mut skipped = 0;
    for k in 0..poses.len().saturating_sub(1) {
        let (a, b) = (poses[k], poses[k + 1]);
        let lo = a.first_sample;
        let hi = b.first_sample + b.n - 1;
        let (i0, i1) = (a.first_sample + a.n - 1, b.first_sample);
        if i1 <= i0 || hi <= lo {
            skipped += 1;
            continue;
        }
        let t = &series.t_s[lo..=hi];
        let nominal_s = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
        if t.windows(2)
            .any(|w| !(w[1] - w[0] > 0.0 && w[1] - w[0] < 1.5 * nominal_s))
        {
            // Lost samples: the rate over the gap is unknown.
            skipped += 1;
            continue;
        }
        // Straight line of time against sample index over both poses and the move.
        let n = t.len() as f64;
        let x_mean = (n - 1.0) / 2.0;
        let t_mean = t.iter().sum::<f64>() / n;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (i, ti) in t.iter().enumerate() {
            let dx = i as f64 - x_mean;
            sxy += dx * (ti - t_mean);
            sxx += dx * dx;
        }
        let period_s = sxy / sxx;
        let time = |i: usize| t_mean + period_s * ((i - lo) as f64 - x_mean);
        let mid_a = time(a.first_sample) + 0.5 * period_s * (a.n - 1) as f64;
        let mid_b = time(b.first_sample) + 0.5 * period_s * (b.n - 1) as f64;
        let (ga, gb) = (a.mean_gyro(), b.mean_gyro());
        let weight_b = |t_s: f64| (t_s - mid_a) / (mid_b - mid_a);
        let rate_rad_s: Vec<Vec3> = (i0..=i1)
            .map(|i| {
                let w = weight_b(time(i));
                Vec3::from(series.gyro_rad_s[i]) - (ga * (1.0 - w) + gb * w)
            })
            .collect();
        let duration_s = period_s * (i1 - i0) as f64;
        // Integrals of the interpolation weights over the move, for the bias error.
        let (mut int_a, mut int_b) = (0.0, 0.0);
        for i in i0..i1 {
            let w = 0.5 * (weight_b(time(i)) + weight_b(time(i + 1)));
            int_a += (1.0 - w) * period_s;
            int_b += w * period_s;
        }
        // Per-axis variances averaged over the axes: white gyro noise integrated over the
        // move, the error of the two pose rates weighted by their share of the interpolation,
        // and the error of the two gravity directions.
        let mean_sq = |v: Vec3| v.norm_squared() / 3.0;
        let white_var =
            (mean_sq(Vec3::from(a.std_gyro_rad_s)) + mean_sq(Vec3::from(b.std_gyro_rad_s))) / 2.0;
        let var_rad2 = white_var * period_s * duration_s
            + int_a * int_a * mean_sq(mean_se(a.std_gyro_rad_s, a.n))
            + int_b * int_b * mean_sq(mean_se(b.std_gyro_rad_s, b.n))
            + (mean_sq(mean_se(a.std_accel_m_s2, a.n)) + mean_sq(mean_se(b.std_accel_m_s2, b.n)))
                / (g_m_s2 * g_m_s2);
        let (e1, e2) = normal_basis(up[k + 1]);
        out.push(MoveData {
            from_pose: k,
            to_pose: k + 1,
            rate_rad_s,
            step_s: period_s,
            up_before: up[k],
            e1,
            e2,
            conditions: conditions[k],
            sigma_rad: var_rad2.sqrt().max(1e-12),
        });
    }
    (out, skipped)
}

/// Gyro offsets (bias, g-sensitivity, ...) from the still-pose means with `fit.rs`.
fn fit_gyro_static(
    poses: &[&Segment],
    up: &[Vec3],
    conditions: &[Conditions],
    model: &TriadModel,
    opts: &ReferenceFreeOptions,
    g_m_s2: f64,
) -> Result<FitResult, FitError> {
    let (vertical_rad_s, horizontal_rad_s) = match opts.latitude_deg {
        Some(lat) => imu_model::earth::earth_rate_split_rad_s(lat),
        None => (0.0, EARTH_RATE_RAD_S),
    };
    let points: Vec<FitPoint> = poses
        .iter()
        .zip(up)
        .zip(conditions)
        .map(|((s, u), c)| FitPoint {
            // Specific force points up at rest, so up is the unit's z in the local level frame.
            true_input: u * vertical_rad_s,
            measured: s.mean_gyro(),
            std_error: mean_se(s.std_gyro_rad_s, s.n),
            conditions: Conditions {
                specific_force_m_s2: u * g_m_s2,
                ..*c
            },
            t_s: 0.5 * (s.start_s + s.end_s),
            duration_s: s.end_s - s.start_s,
        })
        .collect();
    let fit_opts = FitOptions {
        max_iterations: opts.lsq.max_iterations,
        tolerance: opts.lsq.tolerance,
        min_eigenvalue: opts.lsq.min_eigenvalue,
        fixed: held(Triad::Gyro, &model.param_names(Triad::Gyro), &opts.hold),
        bias_drift: opts.gyro_bias_drift_rad_s,
        bias_input_uncertainty: Some([horizontal_rad_s; 3]),
        drift_model: false,
        noise: None,
        shared_noise: None,
    };
    fit_triad(model, Triad::Gyro, &points, &fit_opts)
}

/// Detect the still poses of `series` and fit the accel model to the gravity magnitude and
/// the gyro model to the still poses and the rotations between them (see the module docs).
///
/// A fitted model imud would reject (in practice a cubic nonlinearity that poses within +/-1 g
/// cannot pin down, extrapolated over the +/-20 g range where the model must stay invertible)
/// is refitted with the offending parameter held at 0 (no such term); a note and the
/// unobservable list say so.
pub fn calibrate_reference_free(
    series: &ImuSeries,
    opts: &ReferenceFreeOptions,
) -> Result<ReferenceFreeFit, ReferenceFreeError> {
    let mut opts = opts.clone();
    let mut held: Vec<(Triad, Unobservable)> = Vec::new();
    loop {
        let mut fit = calibrate_reference_free_once(series, &opts)?;
        let invalid = [Triad::Accel, Triad::Gyro].into_iter().find_map(|t| {
            fit.calibration
                .triad(t)
                .validate(t)
                .err()
                .map(|e| (t, crate::fit::invalid_param_name(&e.key), e.message))
        });
        let Some((triad, name, message)) = invalid else {
            for (t, u) in held {
                fit.notes
                    .push(format!("{t} {} not fitted: {}", u.name, u.reason));
                let f = if t == Triad::Gyro {
                    &mut fit.gyro
                } else {
                    &mut fit.accel
                };
                f.unobservable.push(u);
            }
            return Ok(fit);
        };
        let key = format!("{triad}.{name}");
        let f = if triad == Triad::Gyro {
            &fit.gyro
        } else {
            &fit.accel
        };
        let Some(i) = f.names.iter().position(|n| *n == name) else {
            return Err(ReferenceFreeError::InvalidModel {
                triad,
                key: name,
                message,
            });
        };
        if opts.hold.contains(&key) {
            return Err(ReferenceFreeError::InvalidModel {
                triad,
                key: name,
                message,
            });
        }
        let se = f.std_errors[i].map_or_else(String::new, |s| format!(" +/- {s:.2e}"));
        held.push((
            triad,
            Unobservable {
                name,
                reason: format!(
                    "fitted to {:.3e}{se}, it makes the model invalid ({message}); held at 0 (no \
                     such term)",
                    f.params[i]
                ),
            },
        ));
        opts.hold.push(key);
        let m = if triad == Triad::Gyro {
            &mut opts.gyro
        } else {
            &mut opts.accel
        };
        let mut p = m.params();
        p[i] = 0.0;
        m.set_params(&p);
    }
}

/// One reference-free fit of the options as given (see [`calibrate_reference_free`]).
fn calibrate_reference_free_once(
    series: &ImuSeries,
    opts: &ReferenceFreeOptions,
) -> Result<ReferenceFreeFit, ReferenceFreeError> {
    for h in &opts.hold {
        let known = [(Triad::Accel, &opts.accel), (Triad::Gyro, &opts.gyro)]
            .iter()
            .any(|(t, m)| m.param_names(*t).iter().any(|n| *h == format!("{t}.{n}")));
        if !known {
            return Err(ReferenceFreeError::UnknownHold(h.clone()));
        }
    }
    let segmentation = crate::segment::detect(series, &opts.segment)?;
    let mut notes = Vec::new();
    let (g_m_s2, gravity_note) = local_gravity(opts.gravity_m_s2, opts.latitude_deg);
    notes.push(gravity_note);
    let seg_opts = &segmentation.options;
    let still_s = seg_opts.min_duration_s + seg_opts.window_s + 2.0 * seg_opts.trim_s;
    let pose_index: Vec<usize> = (0..segmentation.segments.len())
        .filter(|&i| segmentation.segments[i].kind == SegmentKind::Static)
        .collect();
    let poses: Vec<&Segment> = pose_index
        .iter()
        .map(|&i| &segmentation.segments[i])
        .collect();
    if segmentation.count(SegmentKind::Plateau) > 0 {
        notes.push(format!(
            "{} rate plateau(s) ignored: this procedure uses still poses and the moves between \
             them",
            segmentation.count(SegmentKind::Plateau)
        ));
    }

    let accel = fit_accel(series, &poses, opts, g_m_s2, still_s)?;
    if accel.fit.model.has(EffectKind::Misalignment) {
        notes.push(
            "gauge: accel misalignment xy, xz, yz held at 0 (the gravity magnitude cannot see a \
             rotation of the whole frame): the accelerometer axes define the body frame (accel \
             x = body x, accel y in the body x-y plane) and the gyro is calibrated into that \
             frame"
                .into(),
        );
    }
    let conditions: Vec<Conditions> = poses.iter().map(|s| pose_conditions(series, s)).collect();

    // Gyro: split the model into offsets (still poses) and gains (moves).
    let gyro_model = opts.gyro.effects_only();
    let mut offsets = TriadModel::default();
    let mut gains = TriadModel::default();
    for k in gyro_model.kinds() {
        if GYRO_GAIN_KINDS.contains(&k) {
            gains.add(k);
        } else {
            offsets.add(k);
        }
    }
    let names = gyro_model.param_names(Triad::Gyro);
    let start = gyro_model.params();
    let start_of = |m: &mut TriadModel| {
        let p: Vec<f64> = m
            .param_names(Triad::Gyro)
            .iter()
            .map(|n| start[names.iter().position(|x| x == n).expect("same effects")])
            .collect();
        m.set_params(&p);
    };
    start_of(&mut offsets);
    start_of(&mut gains);

    let gyro_static = if offsets.n_params() > 0 {
        Some(fit_gyro_static(
            &poses,
            &accel.up,
            &conditions,
            &offsets,
            opts,
            g_m_s2,
        )?)
    } else {
        None
    };
    notes.push(match opts.latitude_deg {
        Some(lat) => format!(
            "gyro bias: Earth's vertical rate at latitude {lat} deg removed at each pose; the \
             horizontal part ({:.1e} rad/s, direction unknown without a heading) is carried in \
             the bias standard errors",
            imu_model::earth::earth_rate_split_rad_s(lat).1
        ),
        None => format!(
            "gyro bias: Earth's rate (up to {EARTH_RATE_RAD_S:.2e} rad/s, unknown in the sensor \
             frame without latitude and heading) is carried in the bias standard errors; give \
             --latitude-deg to remove its vertical part"
        ),
    });

    let (moves, skipped) = prepare_moves(series, &poses, &accel.up, &conditions, g_m_s2);
    if skipped > 0 {
        notes.push(format!(
            "{skipped} move(s) skipped: lost samples (the rate over a gap is unknown)"
        ));
    }
    let gain_names = gains.param_names(Triad::Gyro);
    let gain_fit = if gains.n_params() > 0 {
        let n_free = gains.n_params();
        // Two residuals per move.
        let needed = n_free / 2 + 1;
        if moves.len() < needed {
            return Err(ReferenceFreeError::TooFewMoves {
                found: moves.len(),
                skipped,
                needed,
                n_free,
            });
        }
        let fixed = held(Triad::Gyro, &gain_names, &opts.hold);
        let sol = fit_gains(&moves, &gains, &fixed, &opts.lsq).map_err(|source| {
            ReferenceFreeError::Lsq {
                triad: Triad::Gyro,
                source,
            }
        })?;
        gains.set_params(&sol.params);
        Some(sol)
    } else {
        None
    };
    let move_out: Vec<Move> = moves
        .iter()
        .map(|m| {
            let q = m.rotation(&gains);
            let [a, b] = m.residual(&gains);
            Move {
                from_pose: m.from_pose,
                to_pose: m.to_pose,
                duration_s: m.step_s * (m.rate_rad_s.len() - 1) as f64,
                angle_rad: q.angle(),
                error_rad: a.hypot(b),
                std_rad: m.sigma_rad,
            }
        })
        .collect();
    let mut gyro = merge_gyro(
        &gyro_model,
        gyro_static.as_ref(),
        gain_fit.as_ref(),
        &move_out,
        opts.weak_eigenvalue,
    );
    let gyro_held = held(Triad::Gyro, &gyro.names, &opts.hold);
    gyro.unobservable
        .splice(0..0, held_entries(&gyro.names, &gyro_held));
    let not_fitted: Vec<&str> = gyro_model
        .kinds()
        .into_iter()
        .filter(|k| {
            matches!(
                k,
                EffectKind::TempScale | EffectKind::TempBias | EffectKind::Warmup
            )
        })
        .map(|k| k.id())
        .collect();
    if !not_fitted.is_empty() {
        notes.push(format!(
            "gyro {}: fitted only as far as this recording's temperatures and times excite them",
            not_fitted.join(", ")
        ));
    }
    notes.push(
        "gyro gains: the rate is corrected by the interpolated rate of the still poses around \
         each move and integrated over straight-line-fitted sample times; the accel fit's own \
         uncertainty is not propagated into them"
            .into(),
    );

    let poses_out: Vec<Pose> = poses
        .iter()
        .enumerate()
        .map(|(k, s)| Pose {
            segment: pose_index[k],
            t_s: 0.5 * (s.start_s + s.end_s),
            duration_s: s.end_s - s.start_s,
            up: accel.up[k].into(),
            magnitude_error_m_s2: accel.magnitude_error_m_s2[k],
        })
        .collect();
    let mut calibration = Calibration::identity();
    calibration.accel = accel.fit.model.clone();
    calibration.gyro = gyro.model.clone();
    calibration.provenance.procedure = Some(PROCEDURE.into());
    calibration.description = Some(format!(
        "reference-free multi-pose calibration from {} still poses and {} moves",
        poses_out.len(),
        move_out.len()
    ));
    Ok(ReferenceFreeFit {
        segmentation,
        gravity_m_s2: g_m_s2,
        poses: poses_out,
        moves: move_out,
        accel: accel.fit,
        gyro,
        gyro_static,
        calibration,
        notes,
    })
}

/// One gyro result from the still-pose offset fit and the move gain fit.
fn merge_gyro(
    model: &TriadModel,
    offsets: Option<&FitResult>,
    gains: Option<&LsqSolution>,
    moves: &[Move],
    weak: f64,
) -> TriadFit {
    let triad = Triad::Gyro;
    let mut model = model.clone();
    let names = model.param_names(triad);
    let units = model.param_units(triad);
    let mut params = model.params();
    let mut std_errors = vec![None; params.len()];
    let mut unobservable = Vec::new();
    let mut warnings = Vec::new();
    // (index in the merged layout, correlation block id, index in that block's free list)
    let mut free_src: Vec<(usize, usize, usize)> = Vec::new();
    if let Some(o) = offsets {
        for (c, &i) in o.free.iter().enumerate() {
            let j = names.iter().position(|n| *n == o.names[i]).expect("subset");
            free_src.push((j, 0, c));
        }
        for (i, n) in o.names.iter().enumerate() {
            let j = names.iter().position(|x| x == n).expect("subset");
            params[j] = o.params[i];
            std_errors[j] = o.std_errors[i];
        }
        unobservable.extend(o.unobservable.iter().cloned());
        warnings.extend(
            o.warnings
                .iter()
                .map(|w| format!("gyro (still poses): {w}")),
        );
    }
    let gain_names: Vec<String> = {
        let mut g = TriadModel::default();
        for k in model.kinds() {
            if GYRO_GAIN_KINDS.contains(&k) {
                g.add(k);
            }
        }
        g.param_names(triad)
    };
    if let Some(s) = gains {
        for (c, &i) in s.free.iter().enumerate() {
            let j = names
                .iter()
                .position(|n| *n == gain_names[i])
                .expect("subset");
            free_src.push((j, 1, c));
        }
        for (i, n) in gain_names.iter().enumerate() {
            let j = names.iter().position(|x| x == n).expect("subset");
            params[j] = s.params[i];
            std_errors[j] = s.std_errors[i];
        }
        unobservable.extend(s.unobservable.iter().cloned());
        warnings.extend(conditioning_warnings(triad, s, &gain_names, weak, "moves"));
    }
    free_src.sort_by_key(|f| f.0);
    let correlation: Vec<Vec<f64>> = free_src
        .iter()
        .map(|a| {
            free_src
                .iter()
                .map(|b| match (a.1, b.1) {
                    (0, 0) => offsets.map_or(0.0, |o| o.correlation[a.2][b.2]),
                    (1, 1) => gains.map_or(0.0, |s| s.correlation[a.2][b.2]),
                    _ => 0.0,
                })
                .collect()
        })
        .collect();
    model.set_params(&params);
    store_std_errors(&mut model, &std_errors, &[]);
    if let Some(o) = offsets {
        model.residual_rms = Some(o.residual_rms);
    }
    let n = moves.len().max(1) as f64;
    let residual_rms = (moves.iter().map(|m| m.error_rad.powi(2)).sum::<f64>() / (2.0 * n)).sqrt();
    TriadFit {
        triad,
        model,
        names,
        units,
        params,
        std_errors,
        free: free_src.iter().map(|f| f.0).collect(),
        correlation,
        unobservable,
        residual: "predicted minus measured gravity direction after each move, per component"
            .into(),
        residual_unit: "rad".into(),
        residual_rms,
        n_residuals: 2 * moves.len(),
        chi2: gains.map_or(0.0, |s| s.chi2),
        dof: gains.map_or(0, |s| s.dof),
        reduced_chi2: gains.map_or(f64::NAN, |s| s.reduced_chi2),
        min_eigenvalue: gains.map_or(f64::NAN, |s| s.min_eigenvalue),
        iterations: gains.map_or(0, |s| s.iterations),
        converged: gains.is_none_or(|s| s.converged),
        warnings,
    }
}

/// `diag(1 + s) (I + M)` of a triad model's scale and misalignment (identity where absent).
fn gain_matrix(m: &TriadModel) -> Matrix3<f64> {
    let s = m.scale.as_ref().map_or([0.0; 3], |s| s.value);
    let mis = m
        .misalignment
        .as_ref()
        .map_or(Matrix3::identity(), |x| x.matrix());
    Matrix3::from_diagonal(&Vec3::new(1.0 + s[0], 1.0 + s[1], 1.0 + s[2])) * mis
}

/// Writes `k = diag(1 + s) (I + M)` back as scale and misalignment effects of `m`.
fn set_gain_matrix(m: &mut TriadModel, k: &Matrix3<f64>) {
    m.add(EffectKind::Scale);
    m.add(EffectKind::Misalignment);
    if let Some(s) = m.scale.as_mut() {
        s.value = [k[(0, 0)] - 1.0, k[(1, 1)] - 1.0, k[(2, 2)] - 1.0];
    }
    if let Some(x) = m.misalignment.as_mut() {
        let r = |i: usize, j: usize| k[(i, j)] / k[(i, i)];
        (x.xy, x.xz, x.yx, x.yz, x.zx, x.zy) =
            (r(0, 1), r(0, 2), r(1, 0), r(1, 2), r(2, 0), r(2, 1));
    }
}

/// A truth model re-expressed in the body frame this procedure's gauge defines (accel axes:
/// accel x = body x, accel y in the body x-y plane), for comparing a reference-free fit with
/// it. With the truth's accel gains `K = L Q` (`L` lower triangular with a positive diagonal,
/// `Q` a rotation from the truth's sensor frame to the body frame), the accel gains become `L`
/// and every vector input of the other triads is rotated by `Q`: gyro gains `K_g Q^T`,
/// g-sensitivity `G Q^T`, lever arm `Q r`. Biases and per-axis effects are unchanged.
pub fn in_accel_frame(truth: &Calibration) -> Calibration {
    let mut out = truth.clone();
    if !(truth.accel.has(EffectKind::Misalignment) || truth.accel.has(EffectKind::Scale)) {
        return out;
    }
    let k = gain_matrix(&truth.accel);
    let qr = k.transpose().qr();
    let (q1, r) = (qr.q(), qr.r());
    let d = Matrix3::from_diagonal(&Vec3::new(
        r[(0, 0)].signum(),
        r[(1, 1)].signum(),
        r[(2, 2)].signum(),
    ));
    let lower = (d * r).transpose();
    let body_from_sensor = (q1 * d).transpose();
    set_gain_matrix(&mut out.accel, &lower);
    if let Some(l) = out.accel.lever_arm.as_mut() {
        l.offset_m = (body_from_sensor * Vec3::from(l.offset_m)).into();
    }
    if truth.gyro.has(EffectKind::Misalignment) || truth.gyro.has(EffectKind::Scale) {
        let kg = gain_matrix(&truth.gyro) * body_from_sensor.transpose();
        set_gain_matrix(&mut out.gyro, &kg);
    } else if !truth.gyro.is_empty() {
        set_gain_matrix(&mut out.gyro, &body_from_sensor.transpose());
    }
    if let Some(g) = out.gyro.g_sensitivity.as_mut() {
        let m = Matrix3::from_fn(|i, j| g.matrix[i][j]) * body_from_sensor.transpose();
        g.matrix = std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]));
    }
    out
}

#[cfg(test)]
mod tests {
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
        let t = truth();
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
            for _ in 0..1200 {
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
        assert!(fit.notes.iter().any(|n| n.contains("gauge")));
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
        let w = fit.accel.warnings.join("\n");
        assert!(w.contains("barely separate"), "{w}");
        assert!(w.contains("accel x: the axis never pointed"), "{w}");
        assert!(
            w.contains("accel z: the axis never pointed within 45 degrees of down"),
            "{w}"
        );
    }
}
