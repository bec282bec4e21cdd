//! Calibration health: a calibration held against physics whenever the unit is still. The
//! daemon runs it live on its corrected stream (`imud`'s `health` module is an adapter to its
//! configuration and bus types); [`check_series`] runs the same detector and tests offline over
//! a recording (`imu-analyze health`, `imud.health_check`).
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
//! gravity only otherwise) and reported with every window.
//!
//! Files: `still.rs` the incremental still detector, `reference.rs` a window against gravity
//! and Earth's rate, `check.rs` the offline check of a whole recording; here the options, the
//! per-triad sequential test and its states, the offset estimators and [`Monitor`].

pub mod check;
pub mod reference;
pub mod still;

use std::collections::VecDeque;

use imu_model::{Calibration, Mat3, Vec3};
pub use imu_rec::sample::HealthState;
use imu_stats::distributions::chi2_sf;

pub use check::{HealthCheck, StillWindowCheck, check_series};
use reference::{GravityReference, NoiseBasis, TriadNoise, WindowResiduals};
use still::{Detected, StillDetector, StillOptions, StillWindow};

/// Consecutive windows that make a state: three rejections make `stale`, three consistent
/// windows make `ok` again.
pub const RUN_FOR_STATE: u32 = 3;
/// A window is consistent (counts towards `ok`) above this p-value.
pub const CONSISTENT_P: f64 = 0.01;
/// Windows kept for the live offset estimate.
const OFFSET_HISTORY: usize = 30;

/// The gravity a still window's specific force is held against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gravity {
    /// Known (a survey, a gravimeter), m/s^2.
    Known(f64),
    /// Normal gravity at [`CheckOptions::latitude_deg`] and [`CheckOptions::height_m`]
    /// (`imu_model::earth::normal_gravity_m_s2`); learned when no latitude is given.
    Normal,
    /// Learned from the first still windows: only changes are seen.
    Learned,
}

impl Gravity {
    /// The daemon's `[health]` rule: a configured value, else normal gravity at a configured
    /// latitude, else learned.
    pub fn from_settings(gravity_m_s2: Option<f64>, latitude_deg: Option<f64>) -> Gravity {
        match (gravity_m_s2, latitude_deg) {
            (Some(g), _) => Gravity::Known(g),
            (None, Some(_)) => Gravity::Normal,
            (None, None) => Gravity::Learned,
        }
    }
}

/// Everything the health checks are told: the detector's settings, where the unit is, the
/// gravity reference and the false-alarm rate. The defaults are the daemon's `[health]`
/// defaults (its configuration takes them from here).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckOptions {
    /// The still detector.
    pub still: StillOptions,
    /// Latitude, deg: normal gravity and the vertical part of Earth's rate.
    pub latitude_deg: Option<f64>,
    /// Height above the ellipsoid, m (normal gravity's free-air term).
    pub height_m: f64,
    /// The gravity reference.
    pub gravity: Gravity,
    /// p-value below which a still window rejects the calibration: the false-alarm rate per
    /// still window.
    pub false_alarm_p: f64,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            still: StillOptions::default(),
            latitude_deg: None,
            height_m: 0.0,
            gravity: Gravity::Learned,
            false_alarm_p: 1e-4,
        }
    }
}

impl CheckOptions {
    /// The default options at a place: `latitude_deg` (if known), `height_m`, and a known
    /// gravity if given (else normal gravity at the latitude, else learned); what
    /// `imu-analyze health` and `imud.health_check` take.
    pub fn at(
        latitude_deg: Option<f64>,
        height_m: f64,
        gravity_m_s2: Option<f64>,
        false_alarm_p: f64,
    ) -> CheckOptions {
        CheckOptions {
            latitude_deg,
            height_m,
            gravity: Gravity::from_settings(gravity_m_s2, latitude_deg),
            false_alarm_p,
            ..CheckOptions::default()
        }
    }

    /// A sentence naming the first setting out of its range.
    pub fn validate(&self) -> Result<(), String> {
        let s = &self.still;
        if let Some(lat) = self.latitude_deg
            && !(-90.0..=90.0).contains(&lat)
        {
            return Err(format!("latitude {lat} deg is not within -90 to 90"));
        }
        if !self.height_m.is_finite() {
            return Err(format!("height {} m is not a number", self.height_m));
        }
        if let Gravity::Known(g) = self.gravity
            && !(g.is_finite() && g > 0.0)
        {
            return Err(format!("gravity {g} m/s^2 must be a positive number"));
        }
        if !(self.false_alarm_p > 0.0 && self.false_alarm_p < 1.0) {
            return Err(format!(
                "false-alarm p {} must lie between 0 and 1",
                self.false_alarm_p
            ));
        }
        for (name, v) in [
            ("block", s.block_s),
            ("min-still", s.min_still_s),
            ("max-window", s.max_window_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} {v} s must be a positive number of seconds"));
            }
        }
        Ok(())
    }

    /// The reference the options give, before any window.
    fn gravity_reference(&self) -> GravityReference {
        let learned = GravityReference::Learned {
            sum_m_s2: 0.0,
            windows: 0,
        };
        match (self.gravity, self.latitude_deg) {
            (Gravity::Known(g), _) => GravityReference::Known(g),
            (Gravity::Normal, Some(lat)) => {
                GravityReference::Known(imu_model::earth::normal_gravity_m_s2(lat, self.height_m))
            }
            (Gravity::Normal, None) | (Gravity::Learned, _) => learned,
        }
    }
}

/// Where a window's expected scatter came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseSource {
    /// The calibration's noise tables.
    Tables,
    /// Estimated from the scatter within the first still windows (white noise only).
    Estimated,
    /// Not known yet (still estimating): no test was made.
    None,
}

impl NoiseSource {
    /// `tables`, `estimated` or `none`.
    pub fn name(self) -> &'static str {
        match self {
            NoiseSource::Tables => "tables",
            NoiseSource::Estimated => "estimated",
            NoiseSource::None => "none",
        }
    }
}

/// An accel window for the offset estimate: up, |f| - g, its variance.
pub type AccelObs = (Vec3, f64, f64);
/// A gyro window for the offset estimate: the rate residual and its per-axis variance.
pub type GyroObs = (Vec3, [f64; 3]);

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

/// An offset estimate with its covariance (the weighted least squares' inverse normal matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffsetEstimate {
    /// The offset, per sensor axis (NaN without observations).
    pub offset: Vec3,
    /// Its covariance (NaN where unobserved).
    pub covariance: Mat3,
    /// Estimated in 3-D (several orientations); false: along the mean up direction only.
    pub three_d: bool,
}

/// How well the live monitor's windows must span space before its accel offset is solved in
/// 3-D (smallest over largest eigenvalue of the weighted sum of up up^T): the daemon may apply
/// that offset to the stream (`track-bias`), so it waits for well-spread orientations.
pub const LIVE_MIN_SPREAD: f64 = 0.05;

/// The accel bias offset that explains `obs` (up, |f| - g, variance) by weighted least
/// squares: in 3-D when the ups span space (the eigenvalue ratio of their weighted sum of
/// up up^T at least `min_spread`), else along their (weighted) mean direction.
pub fn accel_offset<'a>(
    obs: impl IntoIterator<Item = &'a AccelObs>,
    min_spread: f64,
) -> OffsetEstimate {
    let (mut a, mut b, mut mean_up, mut sw, mut swr, mut n) = (
        Mat3::zeros(),
        Vec3::zeros(),
        Vec3::zeros(),
        0.0,
        0.0,
        0usize,
    );
    for (u, r, var) in obs {
        let w = 1.0 / var.max(1e-300);
        a += u * u.transpose() * w;
        b += u * (r * w);
        mean_up += u * w;
        sw += w;
        swr += r * w;
        n += 1;
    }
    if n == 0 {
        return OffsetEstimate {
            offset: Vec3::repeat(f64::NAN),
            covariance: Mat3::repeat(f64::NAN),
            three_d: false,
        };
    }
    let eig = a.symmetric_eigen().eigenvalues;
    let (lo, hi) = (eig.min(), eig.max());
    if lo > min_spread * hi
        && let Some(inv) = a.try_inverse()
    {
        return OffsetEstimate {
            offset: inv * b,
            covariance: inv,
            three_d: true,
        };
    }
    let up = mean_up.normalize();
    OffsetEstimate {
        offset: up * (swr / sw),
        covariance: up * up.transpose() / sw,
        three_d: false,
    }
}

/// The gyro bias offset that explains `obs`: the weighted mean residual per axis, with its
/// variance on the diagonal.
pub fn gyro_offset<'a>(obs: impl IntoIterator<Item = &'a GyroObs> + Clone) -> OffsetEstimate {
    let mut covariance = Mat3::zeros();
    let offset = Vec3::from_fn(|i, _| {
        let (sw, swr) = obs
            .clone()
            .into_iter()
            .fold((0.0, 0.0), |(sw, swr), (r, var)| {
                let w = 1.0 / var[i].max(1e-300);
                (sw + w, swr + r[i] * w)
            });
        covariance[(i, i)] = if sw > 0.0 { 1.0 / sw } else { f64::NAN };
        if sw > 0.0 { swr / sw } else { f64::NAN }
    });
    OffsetEstimate {
        offset,
        covariance,
        three_d: true,
    }
}

/// The sequential tests of one window (a calibration is held and the noise and gravity are
/// known).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowTest {
    /// The accel window's p-value.
    pub accel_p: f64,
    /// The gyro window's p-value.
    pub gyro_p: f64,
    /// The states before this window (accel, gyro).
    pub before: (HealthState, HealthState),
    /// The accel bias offset that explains the windows since the state left `ok`, m/s^2.
    pub accel_offset_m_s2: Vec3,
    /// It was estimated in 3-D.
    pub accel_offset_3d: bool,
    /// The gyro bias offset that explains them, rad/s.
    pub gyro_offset_rad_s: Vec3,
}

/// What one still window showed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowCheck {
    /// The window.
    pub window: StillWindow,
    /// The sample time that closed it, ns.
    pub closed_ns: u64,
    /// Still windows so far (this one included).
    pub still_windows: u64,
    /// Rate plateaus skipped so far.
    pub plateaus: u64,
    /// Where the expected scatter came from when the window closed (before it was learned
    /// from).
    pub noise_source: NoiseSource,
    /// The gravity the window was held against, m/s^2 (while learning: the reference before
    /// it, NaN until learned).
    pub gravity_m_s2: f64,
    /// The gravity is learned (changes only), not known.
    pub gravity_learned: bool,
    /// The window against physics; `None` while the noise or gravity is being learned.
    pub residuals: Option<WindowResiduals>,
    /// The sequential tests; `None` when no calibration is held or nothing was tested.
    pub test: Option<WindowTest>,
    /// The states after the window (accel, gyro).
    pub states: (HealthState, HealthState),
}

/// The health monitor of one calibration: fed every corrected sample in order, it reports
/// each still window held against physics and the states it leaves.
#[derive(Debug, Clone)]
pub struct Monitor {
    options: CheckOptions,
    detector: StillDetector,
    held: bool,
    noise: NoiseBasis,
    gravity: GravityReference,
    accel: Track<AccelObs>,
    gyro: Track<GyroObs>,
    since_ns: Option<u64>,
    windows: u64,
    plateaus: u64,
}

impl Monitor {
    /// A monitor of the stream corrected by `calibration`: its noise tables give the expected
    /// scatter (without tables, or without a calibration, the scatter is estimated from the
    /// first still windows). `held`: a calibration is held against physics (false: the
    /// stream is uncalibrated, the states stay `uncalibrated` and nothing is tested).
    pub fn new(options: &CheckOptions, calibration: Option<&Calibration>, held: bool) -> Monitor {
        let tables =
            calibration.and_then(|c| Some((TriadNoise::of(&c.accel)?, TriadNoise::of(&c.gyro)?)));
        let expected = tables
            .as_ref()
            .map(|(a, g)| (a.expected_still(), g.expected_still()));
        let initial = if held {
            HealthState::Unknown
        } else {
            HealthState::Uncalibrated
        };
        Monitor {
            options: *options,
            detector: StillDetector::new(options.still, expected),
            held,
            noise: match tables {
                Some((accel, gyro)) => NoiseBasis::Tables { accel, gyro },
                None => NoiseBasis::Estimated {
                    accel: Default::default(),
                    gyro: Default::default(),
                    rate_sum_hz: 0.0,
                    windows: 0,
                },
            },
            gravity: options.gravity_reference(),
            accel: Track::starting(initial),
            gyro: Track::starting(initial),
            since_ns: None,
            windows: 0,
            plateaus: 0,
        }
    }

    /// The options.
    pub fn options(&self) -> &CheckOptions {
        &self.options
    }

    /// The stream was interrupted (a new device session): the current still run is dropped.
    pub fn interrupt(&mut self) {
        self.detector.interrupt();
    }

    /// The states (accel, gyro).
    pub fn states(&self) -> (HealthState, HealthState) {
        (self.accel.state, self.gyro.state)
    }

    /// The accel triad is tested afresh from `ok` (its correction changed: bias tracking).
    pub fn restart_accel(&mut self) {
        self.accel = Track::starting(HealthState::Ok);
    }

    /// The gyro triad is tested afresh from `ok`.
    pub fn restart_gyro(&mut self) {
        self.gyro = Track::starting(HealthState::Ok);
    }

    /// The noise of both triads, `None` while still estimating.
    pub fn noise(&self) -> Option<(TriadNoise, TriadNoise)> {
        self.noise.noise()
    }

    /// Where the expected scatter comes from now.
    pub fn noise_source(&self) -> NoiseSource {
        match (&self.noise, self.noise.noise().is_some()) {
            (NoiseBasis::Tables { .. }, _) => NoiseSource::Tables,
            (NoiseBasis::Estimated { .. }, true) => NoiseSource::Estimated,
            (NoiseBasis::Estimated { .. }, false) => NoiseSource::None,
        }
    }

    /// The gravity reference now and the variance of its own estimate relative to one
    /// window's; `None` while learning.
    pub fn gravity(&self) -> Option<(f64, f64)> {
        self.gravity.value()
    }

    /// The time of the first sample, ns.
    pub fn since_ns(&self) -> Option<u64> {
        self.since_ns
    }

    /// One corrected sample; a report when a still window closed. A sample holding a NaN or
    /// infinite value (a unit's missing reading) is skipped, as a lost one: it would make its
    /// whole block look like motion.
    pub fn push(
        &mut self,
        t_sample_ns: u64,
        accel_m_s2: &[f64; 3],
        gyro_rad_s: &[f64; 3],
        temp_c: f64,
    ) -> Option<WindowCheck> {
        if !accel_m_s2.iter().chain(gyro_rad_s).all(|v| v.is_finite()) {
            return None;
        }
        self.since_ns.get_or_insert(t_sample_ns);
        match self
            .detector
            .push(t_sample_ns, accel_m_s2, gyro_rad_s, temp_c)?
        {
            Detected::Plateau => {
                self.plateaus += 1;
                None
            }
            Detected::Still(w) => Some(self.on_window(&w, t_sample_ns)),
        }
    }

    /// Holds a still window against physics and updates the states.
    fn on_window(&mut self, w: &StillWindow, now_ns: u64) -> WindowCheck {
        self.windows += 1;
        let mut out = WindowCheck {
            window: *w,
            closed_ns: now_ns,
            still_windows: self.windows,
            plateaus: self.plateaus,
            noise_source: self.noise_source(),
            gravity_m_s2: self.gravity.value().map_or(f64::NAN, |g| g.0),
            gravity_learned: matches!(self.gravity, GravityReference::Learned { .. }),
            residuals: None,
            test: None,
            states: self.states(),
        };
        self.noise.learn(w);
        if self.gravity.learn(w) {
            return out;
        }
        let (Some((accel, gyro)), Some(g)) = (self.noise.noise(), self.gravity.value()) else {
            return out;
        };
        let elapsed_s = now_ns.saturating_sub(self.since_ns.unwrap_or(now_ns)) as f64 * 1e-9;
        let r = reference::residuals(w, g, self.options.latitude_deg, (&accel, &gyro), elapsed_s);
        out.gravity_m_s2 = g.0;
        out.residuals = Some(r);
        if self.held {
            out.test = Some(self.test(&r));
            out.states = self.states();
        }
        out
    }

    /// The sequential tests and the offsets.
    fn test(&mut self, r: &WindowResiduals) -> WindowTest {
        let alpha = self.options.false_alarm_p;
        let accel_p = self.accel.p_value(
            [r.accel_residual_m_s2, 0.0, 0.0],
            [r.accel_white_var, 1.0, 1.0],
            [r.accel_var, 1.0, 1.0],
            1,
        );
        let gyro_p = self.gyro.p_value(
            r.gyro_residual_rad_s.into(),
            r.gyro_white_var,
            r.gyro_var,
            3,
        );
        let accel_before =
            self.accel
                .update(accel_p, alpha, (r.up, r.accel_residual_m_s2, r.accel_var));
        let accel = accel_offset(&self.accel.obs, LIVE_MIN_SPREAD);
        let gyro_before = self
            .gyro
            .update(gyro_p, alpha, (r.gyro_residual_rad_s, r.gyro_var));
        WindowTest {
            accel_p,
            gyro_p,
            before: (accel_before, gyro_before),
            accel_offset_m_s2: accel.offset,
            accel_offset_3d: accel.three_d,
            gyro_offset_rad_s: gyro_offset(&self.gyro.obs).offset,
        }
    }
}
