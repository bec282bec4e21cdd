//! Scenario files: the motion, environment and device settings of one simulated test, in TOML.
//!
//! A scenario is a list of segments run in order (static positions, index-table steps, rate-table
//! plateaus, single rotations, impacts, random poses) plus the environment (latitude, gravity,
//! magnetic field, temperature profile) and the device's identity. [`Scenario::compile`] turns it
//! into a [`crate::motion::Timeline`] of analytic motion phases.
//!
//! Every key is kebab-case and unknown keys are errors that name the file and line, so a typo
//! never silently changes a test.

use std::path::{Path, PathBuf};

use imu_model::nalgebra::{Matrix3, Rotation3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use crate::motion::{ImpactTrain, Phase, SegmentInfo, Timeline};

/// Errors loading or checking a scenario.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("{file}: cannot read scenario")]
    Io {
        /// The scenario file.
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The TOML is malformed or has an unknown key or a wrong type.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The scenario file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// The values parse but make no physical sense.
    #[error("{file}: {context}: {message}")]
    Invalid {
        /// The scenario file.
        file: String,
        /// Where in the scenario (e.g. `segment 3 (index-table)`).
        context: String,
        /// What is wrong and how to fix it.
        message: String,
    },
}

/// A parsed scenario file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Scenario {
    /// Short name (used in file names and metadata).
    pub name: String,
    /// What the scenario reproduces (e.g. "paper 3.1.2, 12-position index table about y").
    #[serde(default)]
    pub description: String,
    /// Continuous-mode data rate, Hz.
    #[serde(default = "default_rate_hz")]
    pub rate_hz: f64,
    /// Default random seed (the command line's `--seed` overrides it).
    #[serde(default)]
    pub seed: u64,
    /// Geodetic latitude, degrees (sets the Earth-rate components).
    #[serde(default = "default_latitude_deg")]
    pub latitude_deg: f64,
    /// Magnitude of gravity, m/s^2.
    #[serde(default = "default_gravity_m_s2")]
    pub gravity_m_s2: f64,
    /// Earth's magnetic field in the local East-North-Up frame, gauss.
    #[serde(default = "default_mag_enu_gauss")]
    pub mag_field_enu_gauss: [f64; 3],
    /// Default duration of the automatic move between two static orientations, seconds.
    #[serde(default = "default_transition_s")]
    pub transition_s: f64,
    /// How long the device had been powered on when the scenario clock starts, seconds.
    #[serde(default)]
    pub power_on_before_s: f64,
    /// Default truth error model (imu-model calibration file), relative to the scenario file.
    #[serde(default)]
    pub truth: Option<PathBuf>,
    /// The device's identity and clock.
    #[serde(default)]
    pub device: DeviceSpec,
    /// The sensor temperature over time.
    #[serde(default)]
    pub temperature: TemperatureProfile,
    /// Errors outside the model library, added to the sensor output (not part of the truth
    /// model): periodic disturbances such as a vibrating pump or mains interference. They let
    /// tests check that the model workbench does not blame a library effect for them.
    #[serde(rename = "disturbance", default)]
    pub disturbances: Vec<Disturbance>,
    /// The motion, in order.
    #[serde(rename = "segment", default)]
    pub segments: Vec<SegmentSpec>,
}

fn default_rate_hz() -> f64 {
    100.0
}
fn default_latitude_deg() -> f64 {
    40.0
}
fn default_gravity_m_s2() -> f64 {
    imu_model::units::STANDARD_GRAVITY_M_S2
}
fn default_mag_enu_gauss() -> [f64; 3] {
    // Roughly mid-latitude northern hemisphere: pointing north and down.
    [0.0, 0.22, -0.42]
}
fn default_transition_s() -> f64 {
    2.0
}

/// Identity and clock of the virtual device.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct DeviceSpec {
    /// Serial number reported by command 0xF1.
    pub serial_number: u16,
    /// Firmware version word reported by 0xF0 (N reads as N/1000 . (N%1000)/100 . N%100).
    pub firmware: u16,
    /// Timer tick period, seconds (6.5536 ms on most units; 10 ms on reprogrammed ones).
    pub tick_period_s: f64,
    /// Device oscillator error: positive runs fast against true time, parts per million.
    pub clock_drift_ppm: f64,
    /// Tick counter value at power-on.
    pub initial_ticks: u64,
    /// GainScale EEPROM words.
    pub gain_scale: GainScaleSpec,
    /// Serial line rate in bits/s; in real-time mode the virtual link is paced to it.
    pub baud: u32,
    /// When true the device ignores EEPROM reads (0x28), as a failing unit would: hosts must
    /// report their fallback gains loudly.
    pub eeprom_read_fails: bool,
    /// How long "capture gyro bias" (0x06) takes before it answers, seconds (real-time mode).
    pub capture_bias_s: f64,
}

impl Default for DeviceSpec {
    fn default() -> Self {
        Self {
            serial_number: 1001,
            firmware: 3102,
            tick_period_s: imu_proto::ticks::DEFAULT_TICK_PERIOD_S,
            clock_drift_ppm: 0.0,
            initial_ticks: 0,
            gain_scale: GainScaleSpec::default(),
            baud: 38_400,
            eeprom_read_fails: false,
            capture_bias_s: 3.0,
        }
    }
}

/// GainScale EEPROM values (value = counts x GainScale / 32 768 000).
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct GainScaleSpec {
    /// Accelerometer GainScale (EEPROM 230); full scale = 32767 x gain / 32 768 000 g.
    pub accel: u16,
    /// Gyro GainScale (EEPROM 130); full scale in rad/s likewise.
    pub gyro: u16,
    /// Magnetometer GainScale (EEPROM 232); full scale in gauss likewise.
    pub mag: u16,
}

impl Default for GainScaleSpec {
    fn default() -> Self {
        Self {
            accel: 7000,
            gyro: 10000,
            mag: 2000,
        }
    }
}

/// A sinusoidal disturbance on one triad's output: `amplitude sin(2 pi f t + phase)` per axis.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Disturbance {
    /// `accel` (m/s^2), `gyro` (rad/s) or `mag` (gauss).
    pub triad: imu_model::Triad,
    /// Amplitude per axis, in the triad's unit.
    pub amplitude: [f64; 3],
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Phase at scenario time 0, degrees.
    #[serde(default)]
    pub phase_deg: f64,
}

impl Disturbance {
    /// The disturbance at scenario time `t_s`.
    pub fn at(&self, t_s: f64) -> imu_model::Vec3 {
        let s =
            (std::f64::consts::TAU * self.frequency_hz * t_s + self.phase_deg.to_radians()).sin();
        imu_model::Vec3::from(self.amplitude) * s
    }
}

/// Sensor temperature over time since power-on.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", deny_unknown_fields, rename_all = "kebab-case")]
pub enum TemperatureProfile {
    /// A fixed temperature.
    Constant {
        /// deg C
        #[serde(rename = "value-c")]
        value_c: f64,
    },
    /// Exponential warm-up from ambient to operating temperature (paper Figure 4).
    Warmup {
        /// Temperature at power-on, deg C.
        #[serde(rename = "ambient-c")]
        ambient_c: f64,
        /// Settled operating temperature, deg C.
        #[serde(rename = "operating-c")]
        operating_c: f64,
        /// Time constant, seconds.
        #[serde(rename = "tau-s")]
        tau_s: f64,
    },
    /// A sinusoidal temperature cycle (separates temperature effects from warm-up).
    Cycle {
        /// Mean, deg C.
        #[serde(rename = "mean-c")]
        mean_c: f64,
        /// Amplitude, deg C.
        #[serde(rename = "amplitude-c")]
        amplitude_c: f64,
        /// Period, seconds.
        #[serde(rename = "period-s")]
        period_s: f64,
    },
    /// Piecewise-linear `[time since power-on s, deg C]` points, held at the ends.
    Points {
        /// The points, in increasing time.
        points: Vec<[f64; 2]>,
    },
}

impl Default for TemperatureProfile {
    fn default() -> Self {
        Self::Constant { value_c: 25.0 }
    }
}

impl TemperatureProfile {
    /// Temperature at `time_since_power_on_s`, deg C.
    pub fn temp_c(&self, time_since_power_on_s: f64) -> f64 {
        let t = time_since_power_on_s;
        match self {
            Self::Constant { value_c } => *value_c,
            Self::Warmup {
                ambient_c,
                operating_c,
                tau_s,
            } => operating_c - (operating_c - ambient_c) * (-t / tau_s).exp(),
            Self::Cycle {
                mean_c,
                amplitude_c,
                period_s,
            } => mean_c + amplitude_c * (std::f64::consts::TAU * t / period_s).sin(),
            Self::Points { points } => {
                let i = points.partition_point(|p| p[0] <= t);
                if i == 0 {
                    points[0][1]
                } else if i == points.len() {
                    points[points.len() - 1][1]
                } else {
                    let (a, b) = (points[i - 1], points[i]);
                    a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0])
                }
            }
        }
    }
}

/// A compass or vertical direction in the local level frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Direction {
    /// Geographic north.
    North,
    /// South.
    South,
    /// East.
    East,
    /// West.
    West,
    /// Up (against gravity).
    Up,
    /// Down (along gravity).
    Down,
}

impl Direction {
    /// The direction as a unit vector in East-North-Up.
    pub fn enu(self) -> Vector3<f64> {
        match self {
            Self::East => Vector3::x(),
            Self::West => -Vector3::x(),
            Self::North => Vector3::y(),
            Self::South => -Vector3::y(),
            Self::Up => Vector3::z(),
            Self::Down => -Vector3::z(),
        }
    }
}

/// How the sensor is oriented: where two or three of its axes point, or roll/pitch/yaw.
///
/// Roll, pitch and yaw are the aerospace Z-Y-X angles of the sensor relative to North-East-Down,
/// so all zero means x north, y east, z down (the 3DM-GX1 lying flat on its base).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct OrientationSpec {
    /// Where the sensor x axis points.
    pub x: Option<Direction>,
    /// Where the sensor y axis points.
    pub y: Option<Direction>,
    /// Where the sensor z axis points.
    pub z: Option<Direction>,
    /// Roll about x, degrees.
    pub roll_deg: Option<f64>,
    /// Pitch about y, degrees.
    pub pitch_deg: Option<f64>,
    /// Yaw (heading from north) about z, degrees.
    pub yaw_deg: Option<f64>,
}

impl OrientationSpec {
    /// The orientation as `enu_from_sensor`, or a message saying what is wrong.
    pub fn enu_from_sensor(&self) -> Result<UnitQuaternion<f64>, String> {
        let axes = [self.x, self.y, self.z];
        let n_axes = axes.iter().filter(|a| a.is_some()).count();
        let n_euler = [self.roll_deg, self.pitch_deg, self.yaw_deg]
            .iter()
            .filter(|a| a.is_some())
            .count();
        if n_axes > 0 && n_euler > 0 {
            return Err(
                "give either axis directions (x/y/z) or roll-deg/pitch-deg/yaw-deg, not both"
                    .into(),
            );
        }
        if n_axes > 0 {
            if n_axes < 2 {
                return Err("give the directions of at least two sensor axes, e.g. { x = \"north\", z = \"up\" }".into());
            }
            let v: Vec<Option<Vector3<f64>>> = axes.iter().map(|a| a.map(Direction::enu)).collect();
            let (x, y, z) = match (v[0], v[1], v[2]) {
                (Some(x), Some(y), None) => (x, y, x.cross(&y)),
                (Some(x), None, Some(z)) => (x, z.cross(&x), z),
                (None, Some(y), Some(z)) => (y.cross(&z), y, z),
                (Some(x), Some(y), Some(z)) => (x, y, z),
                _ => unreachable!("at least two axes are given"),
            };
            let m = Matrix3::from_columns(&[x, y, z]);
            if (m.transpose() * m - Matrix3::identity()).norm() > 1e-9 || m.determinant() < 0.5 {
                return Err(format!(
                    "the axis directions {:?} do not form a right-handed orthogonal frame",
                    axes
                ));
            }
            return Ok(UnitQuaternion::from_rotation_matrix(
                &Rotation3::from_matrix_unchecked(m),
            ));
        }
        let d = |v: Option<f64>| v.unwrap_or(0.0).to_radians();
        let ned_from_sensor =
            UnitQuaternion::from_euler_angles(d(self.roll_deg), d(self.pitch_deg), d(self.yaw_deg));
        Ok(enu_from_ned() * ned_from_sensor)
    }
}

/// The fixed rotation from North-East-Down to East-North-Up.
pub fn enu_from_ned() -> UnitQuaternion<f64> {
    let m = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// A sensor axis, optionally negated: `x`, `+y`, `-z`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSpec(pub Vector3<f64>);

impl<'de> Deserialize<'de> for AxisSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        let (sign, name) = match s.as_bytes().first() {
            Some(b'-') => (-1.0, &s[1..]),
            Some(b'+') => (1.0, &s[1..]),
            _ => (1.0, s.as_str()),
        };
        let v = match name {
            "x" => Vector3::x(),
            "y" => Vector3::y(),
            "z" => Vector3::z(),
            _ => {
                return Err(serde::de::Error::custom(format!(
                    "axis `{s}` is not one of x, y, z, +x, -x, +y, -y, +z, -z"
                )));
            }
        };
        Ok(Self(v * sign))
    }
}

/// One entry of the scenario's `[[segment]]` list.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", deny_unknown_fields, rename_all = "kebab-case")]
pub enum SegmentSpec {
    /// Hold still (after moving to `orientation`, if given and different).
    Static {
        /// Where to be (default: stay).
        #[serde(default)]
        orientation: Option<OrientationSpec>,
        /// How long, seconds; omit on the last segment to run forever.
        #[serde(rename = "duration-s", default)]
        duration_s: Option<f64>,
        /// Move time to reach `orientation`, seconds (default: the scenario's `transition-s`).
        #[serde(rename = "move-s", default)]
        move_s: Option<f64>,
        /// Label for the truth file and reports.
        #[serde(default)]
        label: Option<String>,
    },
    /// Index-table steps about a sensor axis (paper 3.1.2, and the 30-degree dynamic test of 3.4).
    IndexTable {
        /// The table axis, in sensor axes (`y`, `-z`, ...).
        axis: AxisSpec,
        /// Step between positions, degrees.
        #[serde(rename = "step-deg")]
        step_deg: f64,
        /// Number of positions (12 for a full turn in 30-degree steps).
        positions: u32,
        /// Dwell at each position, seconds.
        #[serde(rename = "dwell-s")]
        dwell_s: f64,
        /// Time of each step, seconds.
        #[serde(rename = "move-s", default = "default_move_s")]
        move_s: f64,
    },
    /// Rate-table plateaus about a sensor axis (paper 3.2.3, Figure 7).
    RateSteps {
        /// The table axis, in sensor axes.
        axis: AxisSpec,
        /// Plateau rates in order, deg/s.
        #[serde(rename = "rates-deg-s")]
        rates_deg_s: Vec<f64>,
        /// Time on each plateau, seconds.
        #[serde(rename = "dwell-s")]
        dwell_s: f64,
        /// Table angular acceleration between plateaus, deg/s^2.
        #[serde(rename = "accel-deg-s2", default = "default_accel_deg_s2")]
        accel_deg_s2: f64,
    },
    /// One rotation by an angle about a sensor axis.
    Rotate {
        /// The axis, in sensor axes.
        axis: AxisSpec,
        /// Angle, degrees (sign follows the right-hand rule about `axis`).
        #[serde(rename = "angle-deg")]
        angle_deg: f64,
        /// Duration, seconds.
        #[serde(rename = "duration-s")]
        duration_s: f64,
    },
    /// A train of half-sine shocks along a sensor axis while otherwise still (paper 3.3).
    Impacts {
        /// Shock direction, in sensor axes.
        axis: AxisSpec,
        /// Number of shocks.
        count: u32,
        /// Time between shocks, seconds.
        #[serde(rename = "period-s")]
        period_s: f64,
        /// Peak specific force of each shock, g.
        #[serde(rename = "peak-g")]
        peak_g: f64,
        /// Duration of each half-sine shock, milliseconds.
        #[serde(rename = "width-ms")]
        width_ms: f64,
    },
    /// Uniformly random static orientations (for reference-free multi-pose calibration).
    RandomPoses {
        /// Number of poses.
        count: u32,
        /// Dwell at each pose, seconds.
        #[serde(rename = "dwell-s")]
        dwell_s: f64,
        /// Move time between poses, seconds.
        #[serde(rename = "move-s", default = "default_move_s")]
        move_s: f64,
    },
}

fn default_move_s() -> f64 {
    2.0
}
fn default_accel_deg_s2() -> f64 {
    40.0
}

impl SegmentSpec {
    fn kind_name(&self) -> &'static str {
        match self {
            Self::Static { .. } => "static",
            Self::IndexTable { .. } => "index-table",
            Self::RateSteps { .. } => "rate-steps",
            Self::Rotate { .. } => "rotate",
            Self::Impacts { .. } => "impacts",
            Self::RandomPoses { .. } => "random-poses",
        }
    }
}

/// Converts a toml parse error into file:line:column.
pub(crate) fn toml_error(file: &str, text: &str, e: &toml::de::Error) -> ScenarioError {
    let mut offset = e.span().map_or(0, |s| s.start);
    // Inside tagged tables (the `kind = ...` segments) toml can only point at the table header;
    // for an unknown or mistyped key, point at the key itself when it follows in that table.
    if let Some(key) = e.message().split('`').nth(1) {
        let start = offset.min(text.len());
        let mut pos = start;
        for (i, line) in text[start..].split_inclusive('\n').enumerate() {
            let trimmed = line.trim_start();
            if i > 0 {
                if trimmed.starts_with('[') {
                    break;
                }
                if trimmed.split(['=', ' ', '\t']).next() == Some(key) {
                    offset = pos + (line.len() - trimmed.len());
                    break;
                }
            }
            pos += line.len();
        }
    }
    let (line, column) = imu_model::line_col(text, offset);
    ScenarioError::Parse {
        file: file.to_string(),
        line,
        column,
        message: e.message().to_string(),
    }
}

impl Scenario {
    /// Parses scenario text; `file` names it in messages.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text).map_err(|e| toml_error(file, text, &e))?;
        s.validate(file)?;
        Ok(s)
    }

    /// Reads and parses a scenario file.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Io {
            file: file.clone(),
            source,
        })?;
        Self::from_toml_str(&text, &file)
    }

    fn validate(&self, file: &str) -> Result<(), ScenarioError> {
        let invalid = |context: String, message: String| ScenarioError::Invalid {
            file: file.to_string(),
            context,
            message,
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        for (i, d) in self.disturbances.iter().enumerate() {
            if !positive(d.frequency_hz) || d.amplitude.iter().any(|a| !a.is_finite()) {
                return Err(invalid(
                    format!("disturbance[{i}]"),
                    "frequency-hz must be positive and the amplitudes finite".into(),
                ));
            }
        }
        if !positive(self.rate_hz) || self.rate_hz > 100_000.0 {
            return Err(invalid(
                "rate-hz".into(),
                format!(
                    "{} Hz is not a usable data rate (0 < rate <= 100000)",
                    self.rate_hz
                ),
            ));
        }
        if !(-90.0..=90.0).contains(&self.latitude_deg) {
            return Err(invalid(
                "latitude-deg".into(),
                format!("{} is outside -90..90 degrees", self.latitude_deg),
            ));
        }
        if !positive(self.gravity_m_s2) || !positive(self.transition_s) {
            return Err(invalid(
                "gravity-m-s2 / transition-s".into(),
                "must be positive".into(),
            ));
        }
        if !positive(self.device.tick_period_s) {
            return Err(invalid(
                "device.tick-period-s".into(),
                "must be positive (6.5536e-3 on most units)".into(),
            ));
        }
        if self.device.clock_drift_ppm.abs() >= 1e5 {
            return Err(invalid(
                "device.clock-drift-ppm".into(),
                "must be well under 1e5 ppm".into(),
            ));
        }
        let g = self.device.gain_scale;
        if g.accel == 0 || g.gyro == 0 || g.mag == 0 {
            return Err(invalid(
                "device.gain-scale".into(),
                "GainScale words must be non-zero".into(),
            ));
        }
        match &self.temperature {
            TemperatureProfile::Warmup { tau_s, .. } if !positive(*tau_s) => {
                return Err(invalid(
                    "temperature".into(),
                    "tau-s must be positive".into(),
                ));
            }
            TemperatureProfile::Cycle { period_s, .. } if !positive(*period_s) => {
                return Err(invalid(
                    "temperature".into(),
                    "period-s must be positive".into(),
                ));
            }
            TemperatureProfile::Points { points }
                if points.is_empty() || points.windows(2).any(|w| w[1][0] <= w[0][0]) =>
            {
                return Err(invalid(
                    "temperature".into(),
                    "points need at least one [time-s, temp-c] pair, in strictly increasing time"
                        .into(),
                ));
            }
            _ => {}
        }
        if self.segments.is_empty() {
            return Err(invalid(
                "segment".into(),
                "a scenario needs at least one [[segment]]".into(),
            ));
        }
        let last = self.segments.len() - 1;
        for (i, seg) in self.segments.iter().enumerate() {
            let ctx = format!("segment {} ({})", i + 1, seg.kind_name());
            let bad = |m: &str| Err(invalid(ctx.clone(), m.to_string()));
            match seg {
                SegmentSpec::Static {
                    orientation,
                    duration_s,
                    move_s,
                    ..
                } => {
                    if let Some(o) = orientation {
                        o.enu_from_sensor().map_err(|m| invalid(ctx.clone(), m))?;
                    }
                    match duration_s {
                        None if i != last => {
                            return bad(
                                "only the last segment may omit duration-s (it then runs forever)",
                            );
                        }
                        Some(d) if !positive(*d) => return bad("duration-s must be positive"),
                        _ => {}
                    }
                    if move_s.is_some_and(|m| !positive(m)) {
                        return bad("move-s must be positive");
                    }
                }
                SegmentSpec::IndexTable {
                    step_deg,
                    positions,
                    dwell_s,
                    move_s,
                    ..
                } => {
                    if *positions == 0
                        || !positive(*dwell_s)
                        || !positive(*move_s)
                        || !step_deg.is_finite()
                    {
                        return bad(
                            "positions, dwell-s and move-s must be positive and step-deg finite",
                        );
                    }
                }
                SegmentSpec::RateSteps {
                    rates_deg_s,
                    dwell_s,
                    accel_deg_s2,
                    ..
                } => {
                    if rates_deg_s.is_empty()
                        || !positive(*dwell_s)
                        || !positive(*accel_deg_s2)
                        || rates_deg_s.iter().any(|r| !r.is_finite())
                    {
                        return bad(
                            "rates-deg-s must be a non-empty list; dwell-s and accel-deg-s2 positive",
                        );
                    }
                }
                SegmentSpec::Rotate {
                    angle_deg,
                    duration_s,
                    ..
                } => {
                    if !angle_deg.is_finite() || !positive(*duration_s) {
                        return bad("angle-deg must be finite and duration-s positive");
                    }
                }
                SegmentSpec::Impacts {
                    count,
                    period_s,
                    peak_g,
                    width_ms,
                    ..
                } => {
                    if *count == 0
                        || !positive(*period_s)
                        || !peak_g.is_finite()
                        || !positive(*width_ms)
                        || width_ms * 1e-3 >= *period_s
                    {
                        return bad(
                            "count, period-s and width-ms must be positive, and each shock shorter than the period",
                        );
                    }
                }
                SegmentSpec::RandomPoses {
                    count,
                    dwell_s,
                    move_s,
                } => {
                    if *count == 0 || !positive(*dwell_s) || !positive(*move_s) {
                        return bad("count, dwell-s and move-s must be positive");
                    }
                }
            }
        }
        Ok(())
    }

    /// Earth's rotation in East-North-Up at the scenario latitude, rad/s.
    pub fn earth_rate_enu_rad_s(&self) -> Vector3<f64> {
        let lat = self.latitude_deg.to_radians();
        Vector3::new(0.0, lat.cos(), lat.sin()) * imu_model::units::EARTH_RATE_RAD_S
    }

    /// Builds the motion timeline. `seed` drives the random poses.
    pub fn compile(&self, seed: u64) -> Timeline {
        let mut b = Builder {
            phases: Vec::new(),
            segments: Vec::new(),
            t_s: 0.0,
            q: UnitQuaternion::identity(),
            table_angle_rad: 0.0,
            gravity_m_s2: self.gravity_m_s2,
        };
        // The sensor starts level (roll = pitch = yaw = 0: x north, y east, z down) unless the
        // first segment says otherwise, in which case it starts there without a move.
        b.q = enu_from_ned();
        if let Some(SegmentSpec::Static {
            orientation: Some(o),
            ..
        }) = self.segments.first()
        {
            b.q = o.enu_from_sensor().expect("validated");
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_0f7a_61e5);
        for (i, seg) in self.segments.iter().enumerate() {
            b.table_angle_rad = 0.0;
            let n = i + 1;
            match seg {
                SegmentSpec::Static {
                    orientation,
                    duration_s,
                    move_s,
                    label,
                } => {
                    if let Some(o) = orientation {
                        let target = o.enu_from_sensor().expect("validated");
                        b.move_to(
                            target,
                            move_s.unwrap_or(self.transition_s),
                            &format!("move to segment {n}"),
                        );
                    }
                    let label = label.clone().unwrap_or_else(|| format!("static {n}"));
                    b.hold(duration_s.unwrap_or(f64::INFINITY), "static", &label, None);
                }
                SegmentSpec::IndexTable {
                    axis,
                    step_deg,
                    positions,
                    dwell_s,
                    move_s,
                } => {
                    for p in 0..*positions {
                        let angle = step_deg * p as f64;
                        b.hold(
                            *dwell_s,
                            "static",
                            &format!(
                                "segment {n} position {} ({angle} deg about {})",
                                p + 1,
                                axis_name(axis.0)
                            ),
                            None,
                        );
                        if p + 1 < *positions {
                            b.rotate(
                                axis.0,
                                step_deg.to_radians(),
                                *move_s,
                                &format!("segment {n} step {}", p + 1),
                            );
                        }
                    }
                }
                SegmentSpec::RateSteps {
                    axis,
                    rates_deg_s,
                    dwell_s,
                    accel_deg_s2,
                } => {
                    let accel = accel_deg_s2.to_radians();
                    let mut rate = 0.0;
                    for r in rates_deg_s {
                        let target = r.to_radians();
                        b.ramp(
                            axis.0,
                            rate,
                            target,
                            accel,
                            &format!("segment {n} ramp to {r} deg/s"),
                        );
                        b.spin(
                            axis.0,
                            target,
                            *dwell_s,
                            &format!("segment {n} rate {r} deg/s"),
                        );
                        rate = target;
                    }
                    b.ramp(axis.0, rate, 0.0, accel, &format!("segment {n} stop"));
                }
                SegmentSpec::Rotate {
                    axis,
                    angle_deg,
                    duration_s,
                } => {
                    b.rotate(
                        axis.0,
                        angle_deg.to_radians(),
                        *duration_s,
                        &format!(
                            "segment {n} rotate {angle_deg} deg about {}",
                            axis_name(axis.0)
                        ),
                    );
                }
                SegmentSpec::Impacts {
                    axis,
                    count,
                    period_s,
                    peak_g,
                    width_ms,
                } => {
                    let train = ImpactTrain {
                        axis_sensor: axis.0,
                        peak_m_s2: peak_g * self.gravity_m_s2,
                        width_s: width_ms * 1e-3,
                        period_s: *period_s,
                    };
                    b.hold(
                        *count as f64 * period_s,
                        "impacts",
                        &format!("segment {n} impacts along {}", axis_name(axis.0)),
                        Some(train),
                    );
                }
                SegmentSpec::RandomPoses {
                    count,
                    dwell_s,
                    move_s,
                } => {
                    for p in 0..*count {
                        let target = random_orientation(&mut rng);
                        b.move_to(
                            target,
                            *move_s,
                            &format!("segment {n} move to pose {}", p + 1),
                        );
                        b.hold(
                            *dwell_s,
                            "static",
                            &format!("segment {n} pose {}", p + 1),
                            None,
                        );
                    }
                }
            }
        }
        Timeline::new(
            b.phases,
            b.segments,
            self.gravity_m_s2,
            self.earth_rate_enu_rad_s(),
            Vector3::from(self.mag_field_enu_gauss),
        )
    }
}

fn axis_name(v: Vector3<f64>) -> String {
    let names = ["x", "y", "z"];
    let i = v.iamax();
    if (v.norm() - v[i].abs()).abs() < 1e-12 {
        format!("{}{}", if v[i] < 0.0 { "-" } else { "+" }, names[i])
    } else {
        format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
    }
}

/// A uniformly distributed random rotation (Shoemake's method).
fn random_orientation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    UnitQuaternion::from_quaternion(imu_model::nalgebra::Quaternion::new(
        b * (tau * u3).cos(),
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
    ))
}

/// Accumulates phases while tracking the orientation and time at the end of the last one.
struct Builder {
    phases: Vec<Phase>,
    segments: Vec<SegmentInfo>,
    t_s: f64,
    q: UnitQuaternion<f64>,
    table_angle_rad: f64,
    gravity_m_s2: f64,
}

impl Builder {
    fn new_segment(
        &mut self,
        kind: &str,
        label: &str,
        axis: Option<Vector3<f64>>,
        rate: Option<f64>,
    ) -> u32 {
        let index = self.segments.len() as u32;
        let g_dir = self.q.inverse_transform_vector(&-Vector3::z());
        self.segments.push(SegmentInfo {
            index,
            kind: kind.to_string(),
            label: label.to_string(),
            start_s: self.t_s,
            end_s: None,
            gravity_dir_sensor: g_dir,
            axis_sensor: axis,
            table_rate_rad_s: rate,
        });
        let _ = self.gravity_m_s2;
        index
    }

    fn end_segment(&mut self) {
        if let Some(s) = self.segments.last_mut() {
            s.end_s = self.t_s.is_finite().then_some(self.t_s);
        }
    }

    fn push(
        &mut self,
        segment: u32,
        axis: Vector3<f64>,
        rate0: f64,
        accel: f64,
        duration_s: f64,
        impacts: Option<ImpactTrain>,
    ) {
        let phase = Phase {
            start_s: self.t_s,
            duration_s,
            segment,
            q0: self.q,
            axis_sensor: Unit::new_normalize(axis),
            rate0_rad_s: rate0,
            accel_rad_s2: accel,
            table_angle0_rad: self.table_angle_rad,
            impacts,
        };
        if duration_s.is_finite() {
            let angle = rate0 * duration_s + 0.5 * accel * duration_s * duration_s;
            self.q = phase.q0 * UnitQuaternion::from_axis_angle(&phase.axis_sensor, angle);
            self.table_angle_rad += angle;
        }
        self.t_s += duration_s;
        self.phases.push(phase);
    }

    fn hold(&mut self, duration_s: f64, kind: &str, label: &str, impacts: Option<ImpactTrain>) {
        let seg = self.new_segment(kind, label, None, None);
        self.push(seg, Vector3::z(), 0.0, 0.0, duration_s, impacts);
        self.end_segment();
    }

    /// Rotates by `angle_rad` about a sensor axis with a triangular rate profile.
    fn rotate(&mut self, axis: Vector3<f64>, angle_rad: f64, duration_s: f64, label: &str) {
        let seg = self.new_segment("move", label, Some(axis), None);
        let half = duration_s / 2.0;
        let accel = angle_rad / (half * half);
        self.push(seg, axis, 0.0, accel, half, None);
        self.push(seg, axis, accel * half, -accel, half, None);
        self.end_segment();
    }

    fn move_to(&mut self, target: UnitQuaternion<f64>, duration_s: f64, label: &str) {
        let delta = self.q.inverse() * target;
        if let Some((axis, angle)) = delta.axis_angle()
            && angle > 1e-12
        {
            self.rotate(axis.into_inner(), angle, duration_s, label);
        }
        // Land exactly on the target so that numerical drift never accumulates over many moves.
        self.q = target;
    }

    fn ramp(&mut self, axis: Vector3<f64>, from: f64, to: f64, accel_mag: f64, label: &str) {
        if (to - from).abs() < 1e-15 {
            return;
        }
        let seg = self.new_segment("move", label, Some(axis), None);
        let accel = accel_mag.copysign(to - from);
        self.push(seg, axis, from, accel, (to - from) / accel, None);
        self.end_segment();
    }

    fn spin(&mut self, axis: Vector3<f64>, rate: f64, duration_s: f64, label: &str) {
        let kind = if rate == 0.0 { "static" } else { "rate" };
        let seg = self.new_segment(kind, label, Some(axis), Some(rate));
        self.push(seg, axis, rate, 0.0, duration_s, None);
        self.end_segment();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = r#"
name = "t"
[[segment]]
kind = "static"
duration-s = 1.0
"#;

    #[test]
    fn minimal_scenario_has_documented_defaults() {
        let s = Scenario::from_toml_str(MINIMAL, "t.toml").unwrap();
        assert_eq!(s.rate_hz, 100.0);
        assert_eq!(s.device.gain_scale.accel, 7000);
        assert_eq!(s.device.tick_period_s, 6.5536e-3);
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let text = "name = \"t\"\nrate-hz = 100\nlatitude = 40\n[[segment]]\nkind = \"static\"\nduration-s = 1\n";
        let e = Scenario::from_toml_str(text, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("bad.toml:3:"), "{e}");
        assert!(e.contains("latitude"), "{e}");
    }

    #[test]
    fn bad_axis_is_explained() {
        let text = "name = \"t\"\n[[segment]]\nkind = \"rotate\"\naxis = \"w\"\nangle-deg = 90\nduration-s = 1\n";
        let e = Scenario::from_toml_str(text, "a.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("a.toml:2:") || e.contains("a.toml:4:"), "{e}");
        assert!(e.contains("not one of x, y, z"), "{e}");
    }

    #[test]
    fn endless_segment_only_last() {
        let text = "name = \"t\"\n[[segment]]\nkind = \"static\"\n[[segment]]\nkind = \"static\"\nduration-s = 1\n";
        let e = Scenario::from_toml_str(text, "e.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("segment 1 (static)") && e.contains("only the last"),
            "{e}"
        );
    }

    #[test]
    fn axis_directions_build_right_handed_frames() {
        // Table 1 position 1: spin (z) up, input1 (x) north, input2 (y) west.
        let o = OrientationSpec {
            x: Some(Direction::North),
            z: Some(Direction::Up),
            ..Default::default()
        };
        let q = o.enu_from_sensor().unwrap();
        assert!((q * Vector3::y() - Direction::West.enu()).norm() < 1e-12);
        let bad = OrientationSpec {
            x: Some(Direction::North),
            y: Some(Direction::South),
            ..Default::default()
        };
        assert!(bad.enu_from_sensor().is_err());
        let left = OrientationSpec {
            x: Some(Direction::North),
            y: Some(Direction::East),
            z: Some(Direction::Up),
            ..Default::default()
        };
        assert!(
            left.enu_from_sensor().is_err(),
            "left-handed frame must be refused"
        );
    }

    #[test]
    fn level_euler_zero_is_x_north_z_down() {
        let q = OrientationSpec::default().enu_from_sensor().unwrap();
        assert!((q * Vector3::x() - Direction::North.enu()).norm() < 1e-12);
        assert!((q * Vector3::z() - Direction::Down.enu()).norm() < 1e-12);
    }

    #[test]
    fn temperature_profiles() {
        let w = TemperatureProfile::Warmup {
            ambient_c: 22.0,
            operating_c: 38.0,
            tau_s: 1800.0,
        };
        assert_eq!(w.temp_c(0.0), 22.0);
        assert!((w.temp_c(1800.0) - (38.0 - 16.0 / std::f64::consts::E)).abs() < 1e-9);
        let p = TemperatureProfile::Points {
            points: vec![[0.0, 20.0], [10.0, 30.0]],
        };
        assert_eq!(p.temp_c(-1.0), 20.0);
        assert_eq!(p.temp_c(5.0), 25.0);
        assert_eq!(p.temp_c(11.0), 30.0);
    }
}
