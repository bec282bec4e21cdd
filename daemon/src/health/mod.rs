//! Live calibration health: the calibration in force held against physics whenever the unit is
//! still (issue: "the daemon holds its calibration against physics").
//!
//! Each corrected sample goes to a [`StillDetector`]; each still window it yields is held
//! against gravity and Earth's rate ([`reference::residuals`]) with the scatter the noise model
//! allows for the window's length. Per triad, two chi-square tests (1 degree of freedom for
//! |f| - g, 3 for the rate vector): the latest window alone, and the mean of the latest
//! [`RUN_FOR_STATE`] windows, whose white noise averages down while the coloured part
//! (bias-instability wander, random walk, the calibration's own error) is taken as fully shared
//! (conservative: the windows are minutes apart at most). The smaller p-value, doubled
//! (Bonferroni), is the window's; below `false-alarm-p` it is a rejection, so the false-alarm
//! rate is bounded by design at `false-alarm-p` per still window (at most one window per
//! `max-window-s`: 2880 a day at 30 s, so the default 1e-4 gives at most 0.29 false alarms a
//! day per triad, fewer than one a day for both, in continuous rest; a unit that moves has
//! fewer windows). Against a bias step of five times a window's expected scatter, one window
//! rejects with probability about 0.8 (|f|, one degree of freedom) or 0.6 (rate, three), so a
//! knock is flagged within three still windows in about 95 % of cases (measured in
//! `daemon/tests/health.rs`). States: `ok`; `degraded` after a rejection; `stale`
//! after three rejections in a row; back to `ok` after three consistent windows in a row
//! (p > 0.01). The bias offset that explains the windows since the state left `ok` is
//! estimated by weighted least squares (in 3-D once several orientations were seen; along
//! gravity only otherwise) and reported with every window. With `track-bias`, a stale triad's
//! offset is applied to the corrected stream (bounded by `track-bias-max-*`), logged and
//! recorded, never silently.

pub mod reference;
pub mod still;

use std::collections::VecDeque;

use imu_bus::CalibrationHealth;
use imu_bus::sample::{HealthState, health_checks, health_noise_source};
use imu_model::{Mat3, Vec3};
use imu_stats::distributions::chi2_sf;

use crate::config::HealthConfig;
use crate::pipeline::ActiveCalibration;
use reference::{GravityReference, NoiseBasis, TriadNoise, WindowResiduals};
use still::{Detected, StillDetector, StillOptions, StillWindow};

/// Consecutive windows that make a state: three rejections make `stale`, three consistent
/// windows make `ok` again.
const RUN_FOR_STATE: u32 = 3;
/// A window is consistent (counts towards `ok`) above this p-value.
const CONSISTENT_P: f64 = 0.01;
/// Windows kept for the offset estimate.
const OFFSET_HISTORY: usize = 30;

/// An accel window for the offset estimate: up, |f| - g, its variance.
type AccelObs = (Vec3, f64, f64);
/// A gyro window for the offset estimate: the rate residual and its per-axis variance.
type GyroObs = (Vec3, [f64; 3]);

/// One triad's sequential test; `O` is what a window leaves for the offset estimate.
#[derive(Debug, Clone)]
struct Track<O> {
    state: HealthState,
    bad_run: u32,
    good_run: u32,
    /// Windows since the state left `ok` (or the latest ones while `ok`).
    obs: VecDeque<O>,
    /// The latest windows' residuals (per axis; one for accel) with their white and total
    /// variances, for the test of their mean.
    recent: VecDeque<([f64; 3], [f64; 3], [f64; 3])>,
}

impl<O> Track<O> {
    /// A track in `state` with no history.
    fn starting(state: HealthState) -> Self {
        Track {
            state,
            bad_run: 0,
            good_run: 0,
            obs: VecDeque::new(),
            recent: VecDeque::new(),
        }
    }

    /// The window's p-value: the smaller of the latest window's and the mean of the latest
    /// [`RUN_FOR_STATE`] windows', doubled; `dims` residual components are tested.
    fn p_value(
        &mut self,
        residual: [f64; 3],
        white: [f64; 3],
        total: [f64; 3],
        dims: usize,
    ) -> f64 {
        if self.recent.len() == RUN_FOR_STATE as usize {
            self.recent.pop_front();
        }
        self.recent.push_back((residual, white, total));
        let chi2 = |r: &[f64; 3], v: &[f64; 3]| (0..dims).map(|i| r[i] * r[i] / v[i]).sum::<f64>();
        let p_one = chi2_sf(chi2(&residual, &total), dims as f64);
        if self.recent.len() < RUN_FOR_STATE as usize {
            return p_one;
        }
        let m = self.recent.len() as f64;
        let (mut mean, mut var) = ([0.0; 3], [0.0; 3]);
        for (r, w, t) in &self.recent {
            for i in 0..dims {
                mean[i] += r[i] / m;
                // White parts average down; the coloured part is shared (its mean over the
                // windows, not reduced).
                var[i] += w[i] / (m * m) + (t[i] - w[i]) / m;
            }
        }
        let p_mean = chi2_sf(chi2(&mean, &var), dims as f64);
        (2.0 * p_one.min(p_mean)).min(1.0)
    }

    /// Applies one window's p-value and keeps its observation (from scratch when the state
    /// just left `ok`); returns the state before.
    fn update(&mut self, p: f64, alpha: f64, obs: O) -> HealthState {
        let rejected = p < alpha;
        if rejected {
            self.bad_run += 1;
            self.good_run = 0;
        } else {
            self.bad_run = 0;
            self.good_run = if p > CONSISTENT_P {
                self.good_run + 1
            } else {
                0
            };
        }
        let before = self.state;
        self.state = match before {
            HealthState::Degraded | HealthState::Stale if self.good_run >= RUN_FOR_STATE => {
                HealthState::Ok
            }
            HealthState::Degraded if self.bad_run >= RUN_FOR_STATE => HealthState::Stale,
            HealthState::Degraded | HealthState::Stale => before,
            _ if rejected => HealthState::Degraded,
            _ => HealthState::Ok,
        };
        let was_ok = !matches!(before, HealthState::Degraded | HealthState::Stale);
        if was_ok && self.state == HealthState::Degraded {
            self.obs.clear();
        }
        if self.obs.len() == OFFSET_HISTORY {
            self.obs.pop_front();
        }
        self.obs.push_back(obs);
        before
    }
}

/// The accel bias offset that explains `obs` (up, |f| - g, variance): in 3-D when the ups span
/// space, else along their mean; and whether it was 3-D.
fn accel_offset(obs: &VecDeque<AccelObs>) -> (Vec3, bool) {
    if obs.is_empty() {
        return (Vec3::repeat(f64::NAN), false);
    }
    let (mut a, mut b, mut mean_up, mut sw, mut swr) =
        (Mat3::zeros(), Vec3::zeros(), Vec3::zeros(), 0.0, 0.0);
    for (u, r, var) in obs {
        let w = 1.0 / var.max(1e-300);
        a += u * u.transpose() * w;
        b += u * (r * w);
        mean_up += u * w;
        sw += w;
        swr += r * w;
    }
    let eig = a.symmetric_eigen().eigenvalues;
    let (lo, hi) = (eig.min(), eig.max());
    if lo > 0.05 * hi
        && let Some(x) = a.try_inverse().map(|inv| inv * b)
    {
        return (x, true);
    }
    (mean_up.normalize() * (swr / sw), false)
}

/// The gyro bias offset that explains `obs`: the weighted mean residual per axis.
fn gyro_offset(obs: &VecDeque<GyroObs>) -> Vec3 {
    Vec3::from_fn(|i, _| {
        let (sw, swr) = obs.iter().fold((0.0, 0.0), |(sw, swr), (r, var)| {
            let w = 1.0 / var[i].max(1e-300);
            (sw + w, swr + r[i] * w)
        });
        if sw > 0.0 { swr / sw } else { f64::NAN }
    })
}

/// A health report and the changes it brought.
#[derive(Debug, Clone, PartialEq)]
pub struct HealthEvent {
    /// The report (also published and recorded).
    pub report: CalibrationHealth,
    /// The state changes and bias-tracking steps of this window, in order (the daemon logs
    /// each one's `Display`).
    pub changes: Vec<HealthChange>,
}

/// The triad a [`HealthChange`] concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HealthTriad {
    /// The accelerometers.
    Accel,
    /// The gyroscopes.
    Gyro,
}

impl HealthTriad {
    /// `accel` or `gyro`.
    pub fn name(self) -> &'static str {
        match self {
            HealthTriad::Accel => "accel",
            HealthTriad::Gyro => "gyro",
        }
    }
}

/// One change the health monitor made: programs match on the variant (or its
/// [`code`](Self::code)); the log line is its `Display`.
#[derive(Debug, Clone, PartialEq)]
pub enum HealthChange {
    /// A triad's state changed.
    State {
        /// Which triad.
        triad: HealthTriad,
        /// The state before.
        from: HealthState,
        /// The state now.
        to: HealthState,
        /// The p-value of the window that decided it.
        p: f64,
        /// The report at the change (residuals, offsets, temperature, still-window count).
        report: CalibrationHealth,
        /// The calibration's temperature range, when the report's temperature lies outside it.
        outside_range_c: Option<[f64; 2]>,
    },
    /// Bias tracking applied a step to a stale triad's correction.
    BiasTracking {
        /// Which triad.
        triad: HealthTriad,
        /// The step applied now (m/s^2 or rad/s).
        step: Vec3,
        /// The total applied offset after it, bounded by `bound`.
        total: Vec3,
        /// The bound of the total's norm.
        bound: f64,
    },
}

impl HealthChange {
    /// The stable code: `state_change` or `bias_tracking`.
    pub fn code(&self) -> &'static str {
        match self {
            HealthChange::State { .. } => "state_change",
            HealthChange::BiasTracking { .. } => "bias_tracking",
        }
    }

    /// True for a return to `ok` (logged as information; every other change is a warning).
    pub fn is_recovery(&self) -> bool {
        matches!(
            self,
            HealthChange::State {
                to: HealthState::Ok,
                ..
            }
        )
    }
}

impl std::fmt::Display for HealthChange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HealthChange::State {
                triad,
                from,
                to,
                p,
                report,
                outside_range_c,
            } => {
                f.write_str(&change_line(*triad, *from, *to, *p, report))?;
                if let Some([lo, hi]) = outside_range_c {
                    write!(
                        f,
                        "; the temperature {:.1} C is outside the calibration's range \
                         {lo:.1} to {hi:.1} C (a thermal effect it never saw?)",
                        report.temp_c
                    )?;
                }
                Ok(())
            }
            HealthChange::BiasTracking {
                triad: HealthTriad::Accel,
                step,
                total,
                bound,
            } => write!(
                f,
                "health: accel bias tracking applies {} m/s^2 (total {}, bound {bound:.3})",
                fmt_vec(*step),
                fmt_vec(*total)
            ),
            HealthChange::BiasTracking {
                triad: HealthTriad::Gyro,
                step,
                total,
                bound,
            } => write!(
                f,
                "health: gyro bias tracking applies {} rad/s (total {}, bound {bound:.4})",
                fmt_vec(*step),
                fmt_vec(*total)
            ),
        }
    }
}

/// The live health monitor of one calibration.
#[derive(Debug, Clone)]
pub struct HealthMonitor {
    config: HealthConfig,
    detector: StillDetector,
    calibration_id: u64,
    calibrated: bool,
    /// The temperatures the calibration's data covered, deg C.
    temperature_range_c: Option<[f64; 2]>,
    noise: NoiseBasis,
    gravity: GravityReference,
    accel: Track<AccelObs>,
    gyro: Track<GyroObs>,
    since_ns: Option<u64>,
    windows: u64,
    plateaus: u64,
    /// Bias offsets applied to the corrected stream (bias tracking), m/s^2 and rad/s.
    applied_accel_m_s2: Vec3,
    applied_gyro_rad_s: Vec3,
}

impl HealthMonitor {
    /// A monitor of `calibration` (none: the stream is reported as uncalibrated).
    pub fn new(config: &HealthConfig, calibration: Option<&ActiveCalibration>) -> HealthMonitor {
        let tables = calibration.and_then(|c| {
            Some((
                TriadNoise::of(&c.model.accel)?,
                TriadNoise::of(&c.model.gyro)?,
            ))
        });
        let expected = tables
            .as_ref()
            .map(|(a, g)| (a.expected_still(), g.expected_still()));
        let opts = StillOptions {
            block_s: config.block_s,
            threshold_factor: config.threshold_factor,
            floor_quantile: config.floor_quantile,
            min_still_s: config.min_still_s,
            max_window_s: config.max_window_s,
            plateau_min_rate_rad_s: config.plateau_min_rate_rad_s,
            max_rest_rate_rad_s: config.max_rest_rate_rad_s,
        };
        let gravity = match (config.gravity_m_s2, config.latitude_deg) {
            (Some(g), _) => GravityReference::Known(g),
            (None, Some(lat)) => {
                GravityReference::Known(imu_model::earth::normal_gravity_m_s2(lat, config.height_m))
            }
            (None, None) => GravityReference::Learned {
                sum_m_s2: 0.0,
                windows: 0,
            },
        };
        let calibrated = calibration.is_some();
        let initial = if calibrated {
            HealthState::Unknown
        } else {
            HealthState::Uncalibrated
        };
        HealthMonitor {
            config: config.clone(),
            detector: StillDetector::new(opts, expected),
            calibration_id: calibration.map_or(0, |c| c.id),
            calibrated,
            temperature_range_c: calibration.and_then(|c| c.model.provenance.temperature_range_c),
            noise: match tables {
                Some((accel, gyro)) => NoiseBasis::Tables { accel, gyro },
                None => NoiseBasis::Estimated {
                    accel: Default::default(),
                    gyro: Default::default(),
                    rate_sum_hz: 0.0,
                    windows: 0,
                },
            },
            gravity,
            accel: Track::starting(initial),
            gyro: Track::starting(initial),
            since_ns: None,
            windows: 0,
            plateaus: 0,
            applied_accel_m_s2: Vec3::zeros(),
            applied_gyro_rad_s: Vec3::zeros(),
        }
    }

    /// The stream was interrupted (a new device session): the current still run is dropped.
    pub fn interrupt(&mut self) {
        self.detector.interrupt();
    }

    /// Bias offsets applied to the corrected stream by bias tracking (accel m/s^2, gyro rad/s);
    /// zero unless `track-bias` is on and a triad went stale.
    pub fn applied_offsets(&self) -> (Vec3, Vec3) {
        (self.applied_accel_m_s2, self.applied_gyro_rad_s)
    }

    /// The states (accel, gyro).
    pub fn states(&self) -> (HealthState, HealthState) {
        (self.accel.state, self.gyro.state)
    }

    /// One corrected sample (after bias tracking); returns a report when a still window closed.
    pub fn push(
        &mut self,
        t_sample_ns: u64,
        t_wall_ns: u64,
        accel_m_s2: &[f64; 3],
        gyro_rad_s: &[f64; 3],
        temp_c: f64,
    ) -> Option<HealthEvent> {
        self.since_ns.get_or_insert(t_sample_ns);
        match self
            .detector
            .push(t_sample_ns, accel_m_s2, gyro_rad_s, temp_c)?
        {
            Detected::Plateau => {
                self.plateaus += 1;
                None
            }
            Detected::Still(w) => Some(self.on_window(&w, t_wall_ns, t_sample_ns)),
        }
    }

    /// Holds a still window against physics and updates the states.
    fn on_window(&mut self, w: &StillWindow, t_wall_ns: u64, now_ns: u64) -> HealthEvent {
        self.windows += 1;
        let mut report = self.blank_report(w, t_wall_ns, now_ns);
        let mut changes = Vec::new();
        self.noise.learn(w);
        if self.gravity.learn(w) {
            return HealthEvent { report, changes };
        }
        let (Some((accel, gyro)), Some(g)) = (self.noise.noise(), self.gravity.value()) else {
            return HealthEvent { report, changes };
        };
        let elapsed_s = now_ns.saturating_sub(self.since_ns.unwrap_or(now_ns)) as f64 * 1e-9;
        let r = reference::residuals(w, g, self.config.latitude_deg, (&accel, &gyro), elapsed_s);
        self.fill_residuals(&mut report, &r, g.0);
        if let Some([lo, hi]) = self.temperature_range_c
            && (w.temp_c < lo || w.temp_c > hi)
        {
            report.checks |= health_checks::TEMP_OUT_OF_RANGE;
        }
        if !self.calibrated {
            return HealthEvent { report, changes };
        }
        self.test(&mut report, &r, &mut changes);
        if self.config.track_bias {
            self.track(&report, &mut changes);
        }
        report.accel_state = self.accel.state.code();
        report.gyro_state = self.gyro.state.code();
        report.bias_tracking = u8::from(
            self.applied_accel_m_s2 != Vec3::zeros() || self.applied_gyro_rad_s != Vec3::zeros(),
        );
        HealthEvent { report, changes }
    }

    fn blank_report(&self, w: &StillWindow, t_wall_ns: u64, now_ns: u64) -> CalibrationHealth {
        let nan3 = [f64::NAN; 3];
        CalibrationHealth {
            t_sample_ns: w.end_ns.min(now_ns),
            t_wall_ns,
            window_start_ns: w.start_ns,
            calibration_id: self.calibration_id,
            still_windows: self.windows,
            plateaus_skipped: self.plateaus,
            accel_residual_m_s2: f64::NAN,
            accel_expected_std_m_s2: f64::NAN,
            accel_p: f64::NAN,
            accel_offset_m_s2: nan3,
            gyro_residual_rad_s: f64::NAN,
            gyro_vertical_residual_rad_s: f64::NAN,
            gyro_expected_std_rad_s: f64::NAN,
            gyro_p: f64::NAN,
            gyro_offset_rad_s: nan3,
            gravity_m_s2: self.gravity.value().map_or(f64::NAN, |g| g.0),
            temp_c: w.temp_c,
            accel_state: self.accel.state.code(),
            gyro_state: self.gyro.state.code(),
            checks: 0,
            noise_source: match (&self.noise, self.noise.noise().is_some()) {
                (NoiseBasis::Tables { .. }, _) => health_noise_source::TABLES,
                (NoiseBasis::Estimated { .. }, true) => health_noise_source::ESTIMATED,
                (NoiseBasis::Estimated { .. }, false) => health_noise_source::NONE,
            },
            bias_tracking: 0,
            reserved: [0; 3],
        }
    }

    fn fill_residuals(&self, report: &mut CalibrationHealth, r: &WindowResiduals, g: f64) {
        report.gravity_m_s2 = g;
        report.accel_residual_m_s2 = r.accel_residual_m_s2;
        report.accel_expected_std_m_s2 = r.accel_var.sqrt();
        report.gyro_residual_rad_s = r.gyro_magnitude_residual_rad_s;
        report.gyro_vertical_residual_rad_s = r.gyro_vertical_residual_rad_s;
        report.gyro_expected_std_rad_s = (r.gyro_var.iter().sum::<f64>() / 3.0).sqrt();
        report.checks = health_checks::EARTH_RATE
            | match self.gravity {
                GravityReference::Known(_) => health_checks::GRAVITY,
                GravityReference::Learned { .. } => health_checks::GRAVITY_LEARNED,
            }
            | if self.config.latitude_deg.is_some() {
                health_checks::EARTH_RATE_VERTICAL
            } else {
                0
            };
    }

    /// The sequential tests, the offsets and the state changes.
    fn test(
        &mut self,
        report: &mut CalibrationHealth,
        r: &WindowResiduals,
        log: &mut Vec<HealthChange>,
    ) {
        let alpha = self.config.false_alarm_p;
        let p_accel = self.accel.p_value(
            [r.accel_residual_m_s2, 0.0, 0.0],
            [r.accel_white_var, 1.0, 1.0],
            [r.accel_var, 1.0, 1.0],
            1,
        );
        let p_gyro = self.gyro.p_value(
            r.gyro_residual_rad_s.into(),
            r.gyro_white_var,
            r.gyro_var,
            3,
        );
        let before = self
            .accel
            .update(p_accel, alpha, (r.up, r.accel_residual_m_s2, r.accel_var));
        let (offset, three_d) = accel_offset(&self.accel.obs);
        report.accel_p = p_accel;
        report.accel_offset_m_s2 = offset.into();
        if three_d {
            report.checks |= health_checks::ACCEL_BIAS_3D;
        }
        if self.accel.state != before {
            log.push(self.state_change(
                HealthTriad::Accel,
                before,
                self.accel.state,
                p_accel,
                report,
            ));
        }
        let before = self
            .gyro
            .update(p_gyro, alpha, (r.gyro_residual_rad_s, r.gyro_var));
        report.gyro_p = p_gyro;
        report.gyro_offset_rad_s = gyro_offset(&self.gyro.obs).into();
        if self.gyro.state != before {
            log.push(self.state_change(HealthTriad::Gyro, before, self.gyro.state, p_gyro, report));
        }
    }

    /// A state change, with the calibration's temperature range when the report's temperature
    /// lies outside it.
    fn state_change(
        &self,
        triad: HealthTriad,
        from: HealthState,
        to: HealthState,
        p: f64,
        report: &CalibrationHealth,
    ) -> HealthChange {
        HealthChange::State {
            triad,
            from,
            to,
            p,
            report: *report,
            outside_range_c: self
                .temperature_range_c
                .filter(|_| report.checks & health_checks::TEMP_OUT_OF_RANGE != 0),
        }
    }

    /// Bias tracking: a stale triad's estimated offset is added to the applied correction
    /// (bounded), and the triad is tested afresh against the corrected stream.
    fn track(&mut self, report: &CalibrationHealth, log: &mut Vec<HealthChange>) {
        let max_a = self.config.track_bias_max_m_s2;
        let max_g = self.config.track_bias_max_rad_s;
        if self.accel.state == HealthState::Stale {
            let step = Vec3::from(report.accel_offset_m_s2);
            if step.iter().all(|v| v.is_finite()) {
                let applied = clamp_norm(self.applied_accel_m_s2 + step, max_a);
                log.push(HealthChange::BiasTracking {
                    triad: HealthTriad::Accel,
                    step,
                    total: applied,
                    bound: max_a,
                });
                self.applied_accel_m_s2 = applied;
                self.accel = Track::starting(HealthState::Ok);
            }
        }
        if self.gyro.state == HealthState::Stale {
            let step = Vec3::from(report.gyro_offset_rad_s);
            if step.iter().all(|v| v.is_finite()) {
                let applied = clamp_norm(self.applied_gyro_rad_s + step, max_g);
                log.push(HealthChange::BiasTracking {
                    triad: HealthTriad::Gyro,
                    step,
                    total: applied,
                    bound: max_g,
                });
                self.applied_gyro_rad_s = applied;
                self.gyro = Track::starting(HealthState::Ok);
            }
        }
    }
}

fn clamp_norm(v: Vec3, max: f64) -> Vec3 {
    let n = v.norm();
    if n > max { v * (max / n) } else { v }
}

fn fmt_vec(v: Vec3) -> String {
    format!("[{:+.3e}, {:+.3e}, {:+.3e}]", v[0], v[1], v[2])
}

/// The axis a vector mostly lies along, as `+x` .. `-z`.
fn dominant_axis(v: Vec3) -> String {
    let i = v.iamax();
    format!(
        "{}{}",
        if v[i] >= 0.0 { '+' } else { '-' },
        ['x', 'y', 'z'][i]
    )
}

/// The log line of a state change, with the offset that would explain it.
fn change_line(
    triad: HealthTriad,
    before: HealthState,
    after: HealthState,
    p: f64,
    r: &CalibrationHealth,
) -> String {
    let what = match triad {
        HealthTriad::Accel => {
            let o = Vec3::from(r.accel_offset_m_s2);
            format!(
                "|f| - g = {:+.4} m/s^2 (expected scatter {:.4}); accel bias shift ~ {:.4} m/s^2 along {} {}",
                r.accel_residual_m_s2,
                r.accel_expected_std_m_s2,
                o.norm(),
                dominant_axis(o),
                fmt_vec(o)
            )
        }
        HealthTriad::Gyro => {
            let o = Vec3::from(r.gyro_offset_rad_s);
            format!(
                "|w| - |Omega| = {:+.2e} rad/s (expected scatter {:.2e} per axis); gyro bias shift ~ {:.2e} rad/s ({:.3} deg/s) along {} {}",
                r.gyro_residual_rad_s,
                r.gyro_expected_std_rad_s,
                o.norm(),
                o.norm().to_degrees(),
                dominant_axis(o),
                fmt_vec(o)
            )
        }
    };
    format!(
        "health: {} {} -> {} (p {p:.1e} over still window {}): {what}",
        triad.name(),
        before.name(),
        after.name(),
        r.still_windows
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> CalibrationHealth {
        CalibrationHealth {
            still_windows: 12,
            accel_residual_m_s2: 0.02,
            accel_expected_std_m_s2: 0.001,
            accel_offset_m_s2: [0.0, 0.0, 0.02],
            temp_c: 61.5,
            ..CalibrationHealth::default()
        }
    }

    /// The log level follows the typed target state, never the words of the line.
    #[test]
    fn only_a_return_to_ok_is_a_recovery() {
        let change = |from, to| HealthChange::State {
            triad: HealthTriad::Accel,
            from,
            to,
            p: 1e-6,
            report: report(),
            outside_range_c: None,
        };
        assert!(change(HealthState::Degraded, HealthState::Ok).is_recovery());
        assert!(change(HealthState::Stale, HealthState::Ok).is_recovery());
        assert!(!change(HealthState::Ok, HealthState::Degraded).is_recovery());
        assert!(!change(HealthState::Degraded, HealthState::Stale).is_recovery());
        let tracking = HealthChange::BiasTracking {
            triad: HealthTriad::Gyro,
            step: Vec3::new(1e-4, 0.0, 0.0),
            total: Vec3::new(1e-4, 0.0, 0.0),
            bound: 0.01,
        };
        assert!(!tracking.is_recovery());
        assert_eq!(tracking.code(), "bias_tracking");
        assert_eq!(
            change(HealthState::Ok, HealthState::Degraded).code(),
            "state_change"
        );
    }

    /// The log line is the Display of the typed change: the states, the still window, the
    /// offset's axis and, out of the calibrated range, the temperature.
    #[test]
    fn a_state_change_renders_its_log_line() {
        let c = HealthChange::State {
            triad: HealthTriad::Accel,
            from: HealthState::Ok,
            to: HealthState::Degraded,
            p: 1e-6,
            report: report(),
            outside_range_c: Some([15.0, 35.0]),
        };
        let line = c.to_string();
        assert!(
            line.starts_with("health: accel ok -> degraded (p 1.0e-6 over still window 12): "),
            "{line}"
        );
        assert!(
            line.ends_with(
                "; the temperature 61.5 C is outside the calibration's range 15.0 to 35.0 C \
                 (a thermal effect it never saw?)"
            ),
            "{line}"
        );
        let tracking = HealthChange::BiasTracking {
            triad: HealthTriad::Accel,
            step: Vec3::new(0.0, 0.0, 0.02),
            total: Vec3::new(0.0, 0.0, 0.02),
            bound: 0.5,
        };
        assert_eq!(
            tracking.to_string(),
            "health: accel bias tracking applies [+0.000e0, +0.000e0, +2.000e-2] m/s^2 (total \
             [+0.000e0, +0.000e0, +2.000e-2], bound 0.500)"
        );
    }
}
