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
//!   g-sensitivity to first order) and by the part of the fitted offset effects that the
//!   interpolation misses (a g-sensitivity follows the specific force of each sample, a
//!   temperature bias its temperature), is integrated with a quaternion midpoint rule over the
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
use crate::calibrate::{
    Evidence, FitError, FitOptions, FitPoint, FitResult, FitWarning, FitWarningKind, NotFitted,
    Unobservable, WarningScope, Warnings, fit_triad,
};
use crate::note::{Note, Notes};
use crate::segment::{Segment, SegmentError, SegmentKind, SegmentOptions, Segmentation};
use imu_stats::lsq::{LsqError, LsqOptions, LsqSolution, least_squares, refit_holding};

mod accel;
mod ellipsoid;
mod gyro;
mod moves;
mod poses;

use accel::*;
use gyro::*;
pub(crate) use moves::*;
pub(crate) use poses::*;

/// What to record, in every message about too few or too clustered poses.
pub const POSE_ADVICE: &str = "hold the unit still in 30 or more orientations: each axis up and \
     down, and at 45 degrees in between (resting on an edge, on a corner), turning it about \
     different axes between poses";

/// The procedure, as written into the calibration's provenance.
pub const PROCEDURE: &str = "reference-free multi-pose: accelerometer from the gravity magnitude \
     at still poses, gyro bias from the still poses, gyro gains from the rotations integrated \
     between poses (imu-calibrate --reference-free)";

/// The accel misalignment entries held at 0 to fix the rotation gauge (the upper triangle:
/// `xy`, `xz`, `yz`): indices into `ids`.
pub(crate) fn gauge(ids: &[imu_model::ParamId]) -> Vec<usize> {
    use imu_model::ParamRole;
    (0..ids.len())
        .filter(|&i| {
            ids[i].effect == EffectKind::Misalignment
                && matches!(ids[i].role, ParamRole::Coupling { row, col } if row < col)
        })
        .collect()
}

/// Local gravity for a reference-free fit, m/s^2, and the note saying where it came from: the
/// given value, else WGS-84 normal gravity at the latitude, else standard gravity.
pub fn local_gravity(
    gravity_m_s2: Option<f64>,
    latitude_deg: Option<f64>,
) -> (f64, crate::note::Note) {
    use crate::note::GravitySource;
    let (g_m_s2, source) = match (gravity_m_s2, latitude_deg) {
        (Some(g), _) => (g, GravitySource::Given),
        (None, Some(lat)) => (normal_gravity_m_s2(lat, 0.0), GravitySource::Latitude(lat)),
        (None, None) => (STANDARD_GRAVITY_M_S2, GravitySource::Standard),
    };
    (g_m_s2, crate::note::Note::LocalGravity { g_m_s2, source })
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
    /// errors (see [`crate::calibrate::FitOptions::bias_drift`]).
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
    /// Poor conditioning, held parameters, clustered poses (JSON: `warnings`, the sentences,
    /// and `warning_codes`).
    #[serde(flatten)]
    pub warnings: Warnings,
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
    /// Decisions and conventions (gauge, gravity, Earth rate, what was not fitted);
    /// `--json` has the sentences (`notes`) and codes (`note_codes`).
    #[serde(flatten)]
    pub notes: Notes,
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
    // Each held parameter: its triad, index, key (`triad.param`) and why.
    type Held = (Triad, usize, String, Unobservable);
    let with_held = |held: &[Held]| {
        let mut o = opts.clone();
        for (triad, i, key, _) in held {
            o.hold.push(key.clone());
            let m = if *triad == Triad::Gyro {
                &mut o.gyro
            } else {
                &mut o.accel
            };
            let mut p = m.params();
            p[*i] = 0.0;
            m.set_params(&p);
        }
        o
    };
    let (mut fit, held) = refit_holding(
        |held: &[Held]| calibrate_reference_free_once(series, &with_held(held)),
        |fit: &ReferenceFreeFit, held: &[Held]| {
            let invalid = [Triad::Accel, Triad::Gyro].into_iter().find_map(|t| {
                fit.calibration
                    .triad(t)
                    .validate(t)
                    .err()
                    .map(|e| (t, crate::calibrate::invalid_param_name(&e.key), e.message))
            });
            let Some((triad, name, message)) = invalid else {
                return Ok(None);
            };
            let key = format!("{triad}.{name}");
            let f = if triad == Triad::Gyro {
                &fit.gyro
            } else {
                &fit.accel
            };
            let already = opts.hold.contains(&key) || held.iter().any(|h| h.2 == key);
            let Some(i) = f.names.iter().position(|n| *n == name).filter(|_| !already) else {
                return Err(ReferenceFreeError::InvalidModel {
                    triad,
                    key: name,
                    message,
                });
            };
            let reason = NotFitted::InvalidModel {
                value: f.params[i],
                std_error: f.std_errors[i],
                message,
            };
            Ok(Some((triad, i, key, Unobservable { name, reason })))
        },
    )?;
    for (t, _, _, u) in held {
        fit.notes.push(Note::NotFitted {
            triad: t,
            unobservable: u.clone(),
        });
        let f = if t == Triad::Gyro {
            &mut fit.gyro
        } else {
            &mut fit.accel
        };
        f.unobservable.push(u);
    }
    Ok(fit)
}

/// One reference-free fit of the options as given (see [`calibrate_reference_free`]).
fn calibrate_reference_free_once(
    series: &ImuSeries,
    opts: &ReferenceFreeOptions,
) -> Result<ReferenceFreeFit, ReferenceFreeError> {
    check_holds(opts)?;
    let segmentation = crate::segment::detect(series, &opts.segment)?;
    let mut notes = Notes(segmentation.notes());
    let (g_m_s2, gravity_note) = local_gravity(opts.gravity_m_s2, opts.latitude_deg);
    notes.push(gravity_note);
    let seg_opts = &segmentation.options;
    let still_s = seg_opts.shortest_still_s();
    let pose_index: Vec<usize> = (0..segmentation.segments.len())
        .filter(|&i| segmentation.segments[i].kind == SegmentKind::Static)
        .collect();
    let poses: Vec<&Segment> = pose_index
        .iter()
        .map(|&i| &segmentation.segments[i])
        .collect();
    if segmentation.count(SegmentKind::Plateau) > 0 {
        notes.push(Note::PlateausIgnored {
            count: segmentation.count(SegmentKind::Plateau),
        });
    }

    let accel = fit_accel(series, &poses, opts, g_m_s2, still_s)?;
    notes.extend(accel.start_note.clone());
    if accel.fit.model.has(EffectKind::Misalignment) {
        notes.push(Note::Gauge);
    }
    let GyroOutcome {
        gyro,
        gyro_static,
        moves: move_out,
    } = fit_gyro(series, &poses, &accel, opts, g_m_s2, &mut notes)?;

    let poses_out = poses_out(&poses, &pose_index, &accel);
    let calibration = fitted_calibration(&accel.fit.model, &gyro.model, &poses_out, &move_out);
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

/// The gyro result of a reference-free fit.
struct GyroOutcome {
    /// The merged gyro fit.
    gyro: TriadFit,
    /// The still-pose offset fit, if the model has offsets.
    gyro_static: Option<FitResult>,
    /// The moves between the poses.
    moves: Vec<Move>,
}

/// The gyro fit on the still `poses` whose up directions `accel` found: the model split into
/// offsets (fitted to the still poses) and gains (fitted to the moves), merged; notes appended.
fn fit_gyro(
    series: &ImuSeries,
    poses: &[&Segment],
    accel: &AccelOutcome,
    opts: &ReferenceFreeOptions,
    g_m_s2: f64,
    notes: &mut Notes,
) -> Result<GyroOutcome, ReferenceFreeError> {
    let conditions: Vec<Conditions> = poses.iter().map(|s| pose_conditions(series, s)).collect();

    // Gyro: split the model into offsets (still poses) and gains (moves).
    let gyro_model = opts.gyro.effects_only();
    let (offsets, mut gains) = split_gyro_model(&gyro_model);

    let gyro_static = if offsets.n_params() > 0 {
        Some(fit_gyro_static(
            poses,
            &accel.up,
            &conditions,
            &offsets,
            opts,
            g_m_s2,
        )?)
    } else {
        None
    };
    notes.push(Note::GyroBiasEarthRate {
        latitude_deg: opts.latitude_deg,
    });

    let inputs = MoveInputs {
        series,
        poses,
        up: &accel.up,
        conditions: &conditions,
        g_m_s2,
    };
    // The offsets fitted to the still poses are applied along each move (a g-sensitivity
    // follows the specific force as the unit turns).
    let offsets = gyro_static.as_ref().map(|f| MoveOffsets {
        gyro: &f.model,
        accel: &accel.fit.model,
    });
    notes.extend(offsets.and_then(|o| o.note()));
    let (moves, skipped) = prepare_moves(&inputs, offsets);
    if skipped > 0 {
        notes.push(Note::MovesSkipped { count: skipped });
    }
    let gain_fit = fit_move_gains(&moves, skipped, &mut gains, opts)?;
    let move_out = moves_out(&moves, &gains);
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
    push_gyro_notes(&gyro_model, notes);
    Ok(GyroOutcome {
        gyro,
        gyro_static,
        moves: move_out,
    })
}

/// Each still pose's summary: its segment, time, up direction and magnitude error.
fn poses_out(poses: &[&Segment], pose_index: &[usize], accel: &AccelOutcome) -> Vec<Pose> {
    poses
        .iter()
        .enumerate()
        .map(|(k, s)| Pose {
            segment: pose_index[k],
            t_s: 0.5 * (s.start_s + s.end_s),
            duration_s: s.end_s - s.start_s,
            up: accel.up[k].into(),
            magnitude_error_m_s2: accel.magnitude_error_m_s2[k],
        })
        .collect()
}

/// Checks that every held parameter names one of the models' parameters.
fn check_holds(opts: &ReferenceFreeOptions) -> Result<(), ReferenceFreeError> {
    for h in &opts.hold {
        let known = [(Triad::Accel, &opts.accel), (Triad::Gyro, &opts.gyro)]
            .iter()
            .any(|(t, m)| m.param_names(*t).iter().any(|n| *h == format!("{t}.{n}")));
        if !known {
            return Err(ReferenceFreeError::UnknownHold(h.clone()));
        }
    }
    Ok(())
}

/// The gyro model split into (offsets, gains): the effects the still poses fit and those the
/// moves fit, each starting from the model's values.
fn split_gyro_model(gyro_model: &TriadModel) -> (TriadModel, TriadModel) {
    let mut offsets = TriadModel::default();
    let mut gains = TriadModel::default();
    for k in gyro_model.kinds() {
        if k.is_gain() {
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
    (offsets, gains)
}

/// Fits the gain model `gains` to the moves (setting its values); `None` when it has no
/// parameters, an error when there are too few moves for them.
fn fit_move_gains(
    moves: &[MoveData],
    skipped: usize,
    gains: &mut TriadModel,
    opts: &ReferenceFreeOptions,
) -> Result<Option<LsqSolution>, ReferenceFreeError> {
    let gain_names = gains.param_names(Triad::Gyro);
    if gains.n_params() == 0 {
        return Ok(None);
    }
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
    let sol =
        fit_gains(moves, gains, &fixed, &opts.lsq).map_err(|source| ReferenceFreeError::Lsq {
            triad: Triad::Gyro,
            source,
        })?;
    gains.set_params(&sol.params);
    Ok(Some(sol))
}

/// Each move's summary under the fitted gains.
fn moves_out(moves: &[MoveData], gains: &TriadModel) -> Vec<Move> {
    moves
        .iter()
        .map(|m| {
            let q = m.rotation(gains);
            let [a, b] = m.residual(gains);
            Move {
                from_pose: m.from_pose,
                to_pose: m.to_pose,
                duration_s: m.step_s * (m.rate_rad_s.len() - 1) as f64,
                angle_rad: q.angle(),
                error_rad: a.hypot(b),
                std_rad: m.sigma_rad,
            }
        })
        .collect()
}

/// Notes on the gyro fit: temperature and warm-up effects fitted only as far as excited, and
/// how the gains are found.
fn push_gyro_notes(gyro_model: &TriadModel, notes: &mut Notes) {
    let not_fitted: Vec<EffectKind> = gyro_model
        .kinds()
        .into_iter()
        .filter(|k| {
            matches!(
                k,
                EffectKind::TempScale | EffectKind::TempBias | EffectKind::Warmup
            )
        })
        .collect();
    if !not_fitted.is_empty() {
        notes.push(Note::FittedAsExcited {
            effects: not_fitted,
        });
    }
    notes.push(Note::GyroGainsMethod);
}

/// The calibration of the fitted accel and gyro models, described by its poses and moves.
fn fitted_calibration(
    accel: &TriadModel,
    gyro: &TriadModel,
    poses: &[Pose],
    moves: &[Move],
) -> Calibration {
    let mut calibration = Calibration::identity();
    calibration.accel = accel.clone();
    calibration.gyro = gyro.clone();
    calibration.provenance.procedure = Some(PROCEDURE.into());
    calibration.description = Some(format!(
        "reference-free multi-pose calibration from {} still poses and {} moves",
        poses.len(),
        moves.len()
    ));
    calibration
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
mod tests;
