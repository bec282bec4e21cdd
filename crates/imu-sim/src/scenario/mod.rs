//! Scenario files: the motion, environment and device settings of one simulated test, in TOML.
//!
//! A scenario is a list of segments run in order (static positions, index-table steps, rate-table
//! plateaus, single rotations, impacts, random poses) plus the environment (latitude, gravity,
//! magnetic field, temperature profile) and the device's identity, and for a unit held by hand
//! (`[hand]`, [`HandSpec`]) its tremor and the tilt noise of its poses. [`Scenario::compile`]
//! turns it into a [`crate::motion::Timeline`] of analytic motion phases.
//!
//! Every key is kebab-case and unknown keys are errors that name the file and line, so a typo
//! never silently changes a test.

use std::path::{Path, PathBuf};

use imu_model::nalgebra::{Matrix3, Rotation3, Unit, UnitQuaternion, Vector3};
use imu_proto::DeviceProtocol;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use crate::motion::{ImpactTrain, Phase, SegmentInfo, Timeline};

mod builder;
mod compile;
mod validate;

use builder::*;

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
    /// Hand-held realism (`[hand]`): tremor throughout and the tilt noise of held poses.
    #[serde(default)]
    pub hand: HandSpec,
    /// The motion, in order.
    #[serde(rename = "segment", default)]
    pub segments: Vec<SegmentSpec>,
}

/// A unit held by hand (`[hand]`), off by default. `tremor-deg`: RMS angle of the hand's
/// tremor about each sensor axis, degrees (physiological tremor: ~0.05-0.5), band-limited to
/// `tremor-band-hz` (default 4-12 Hz), throughout the scenario, still poses and moves alike.
/// `tilt-noise-deg`: each held pose (a `static` segment with an `orientation`, each pose of
/// `random-poses`) is off its nominal attitude by a random tilt about a random horizontal axis
/// of up to this many degrees (uniform in +-tilt). Both are seeded (`--seed`) and both are in
/// the truth: the truth file records the motion the sensor really made, and with tremor its
/// still segments are of kind `held` (still but for the tremor), not `static`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct HandSpec {
    /// RMS tremor angle per axis, degrees (0: none).
    pub tremor_deg: f64,
    /// Tremor frequency band, Hz.
    pub tremor_band_hz: [f64; 2],
    /// Largest tilt of a held pose off its nominal attitude, degrees (0: none).
    pub tilt_noise_deg: f64,
}

impl Default for HandSpec {
    fn default() -> Self {
        Self {
            tremor_deg: 0.0,
            tremor_band_hz: [4.0, 12.0],
            tilt_noise_deg: 0.0,
        }
    }
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

/// The IMU base rate of the simulated MIP device (a 3DM-GX5's is 1000 Hz): it streams at this
/// rate divided by the decimation the host sets, so a MIP scenario's `rate-hz` divides it.
pub const MIP_IMU_BASE_RATE_HZ: f64 = 1000.0;

/// The highest output rate of the simulated Xsens unit (an MTi-600's HR outputs): an Xsens
/// scenario's `rate-hz` is a whole number of Hz up to this, as output configurations carry it.
pub const XSENS_MAX_RATE_HZ: f64 = 2000.0;

fn deserialize_protocol<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<DeviceProtocol, D::Error> {
    let name = String::deserialize(d)?;
    name.parse().map_err(serde::de::Error::custom)
}

/// Identity and clock of the virtual device.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct DeviceSpec {
    /// The protocol the device speaks: `"3dm-gx1"` (default), `"mip"`, `"xsens"` or
    /// `"vectornav"` (the command line's `--protocol` overrides it).
    #[serde(deserialize_with = "deserialize_protocol")]
    pub protocol: DeviceProtocol,
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
    /// Serial line rate in bits/s; in real-time mode a 3DM-GX1's link is paced to it. A MIP
    /// device's link is a USB virtual serial port, as on today's units, and is not paced.
    pub baud: u32,
    /// When true the device ignores EEPROM reads (0x28), as a failing unit would: hosts must
    /// report their fallback gains loudly.
    pub eeprom_read_fails: bool,
    /// How long "capture gyro bias" (0x06) takes before it answers, seconds (real-time mode).
    pub capture_bias_s: f64,
    /// The unit powers up streaming, without any command: set up once with the vendor's tool
    /// and saved (a 3DM-GX1 in continuous mode sending raw sensor bits 0x01, a MIP unit with
    /// its IMU stream resumed). The scenario clock starts at power-up (`imu-sim
    /// --power-up-streaming` sets it too).
    pub power_up_streaming: bool,
    /// A unit with GNSS time (`DeviceCore::gnss_time`): a MIP unit's GPS timestamp field
    /// (0x12), an Xsens MTi's UtcTime and a VN-200/300's GPS time carry the true UTC time of
    /// each sample (`gnss-epoch-utc-s` + scenario time), valid except during the `gnss-outage`
    /// windows, when their validity drops and they carry the unit's own propagation on its
    /// drifting clock. Without it a MIP unit's field carries device time since power-on, never
    /// valid, an MTi's UtcTime the true time from 2026-01-01 (valid) and a VN-200/300's GPS
    /// time the true time (valid).
    pub gnss_time: bool,
    /// UTC of scenario time 0, s since the Unix epoch (default 2026-01-01T00:00:00Z): the
    /// scenario's date. A GNSS unit's true time is this plus scenario time, and so is the host
    /// wall clock of an offline recording (`imud --sim --offline`: its stamps, file name and
    /// `started-utc`), so simulated recordings of a fleet can be months apart.
    pub gnss_epoch_utc_s: f64,
    /// Windows of scenario time with no valid GNSS time.
    pub gnss_outage: Vec<GnssOutage>,
    /// Model name a VectorNav unit reports in register 1 (empty: `VN-100T-CR`); a `VN-200...`
    /// or `VN-300...` has GNSS and sends GPS time.
    pub model: String,
}

/// A window of scenario time during which the unit's GNSS time is invalid.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct GnssOutage {
    /// Start, s of scenario time.
    pub start_s: f64,
    /// End, s of scenario time (GNSS time is valid again from here).
    pub end_s: f64,
}

impl DeviceSpec {
    /// True when the unit's GNSS time is valid at scenario time `t_s`.
    pub fn gnss_valid_at(&self, t_s: f64) -> bool {
        self.gnss_time
            && !self
                .gnss_outage
                .iter()
                .any(|o| (o.start_s..o.end_s).contains(&t_s))
    }
}

impl Default for DeviceSpec {
    fn default() -> Self {
        Self {
            protocol: DeviceProtocol::Gx1,
            serial_number: 1001,
            firmware: 3102,
            tick_period_s: imu_proto::ticks::DEFAULT_TICK_PERIOD_S,
            clock_drift_ppm: 0.0,
            initial_ticks: 0,
            gain_scale: GainScaleSpec::default(),
            baud: 38_400,
            eeprom_read_fails: false,
            capture_bias_s: 3.0,
            power_up_streaming: false,
            gnss_time: false,
            gnss_epoch_utc_s: 1_767_225_600.0,
            gnss_outage: Vec::new(),
            model: String::new(),
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

/// An error outside the truth model on one triad's output, per axis: a sinusoid
/// `amplitude sin(2 pi f t + phase)` (`frequency-hz`, optional `phase-deg`), or a step of
/// `amplitude` from `step-at-s` on (a knock that shifts a bias, for the daemon's health tests).
#[derive(Debug, Clone, Deserialize)]
#[serde(try_from = "DisturbanceSpec")]
pub struct Disturbance {
    /// `accel` (m/s^2), `gyro` (rad/s) or `mag` (gauss).
    pub triad: imu_model::Triad,
    /// Amplitude per axis, in the triad's unit.
    pub amplitude: [f64; 3],
    /// Its shape in time.
    pub shape: DisturbanceShape,
}

/// The time course of a [`Disturbance`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DisturbanceShape {
    /// `sin(2 pi f t + phase)`.
    Sine {
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase at scenario time 0, degrees.
        phase_deg: f64,
    },
    /// 0 before `at_s`, 1 from then on.
    Step {
        /// Scenario time of the step, s.
        at_s: f64,
    },
}

/// A `[[disturbance]]` table as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
struct DisturbanceSpec {
    triad: imu_model::Triad,
    amplitude: [f64; 3],
    frequency_hz: Option<f64>,
    phase_deg: Option<f64>,
    step_at_s: Option<f64>,
}

impl TryFrom<DisturbanceSpec> for Disturbance {
    type Error = String;
    fn try_from(d: DisturbanceSpec) -> Result<Self, String> {
        let shape = match (d.frequency_hz, d.step_at_s, d.phase_deg) {
            (Some(frequency_hz), None, phase) => DisturbanceShape::Sine {
                frequency_hz,
                phase_deg: phase.unwrap_or(0.0),
            },
            (None, Some(at_s), None) => DisturbanceShape::Step { at_s },
            _ => {
                return Err(
                    "a disturbance is a sinusoid (`frequency-hz`, optional `phase-deg`) \
                            or a step (`step-at-s`): give one of them"
                        .into(),
                );
            }
        };
        Ok(Disturbance {
            triad: d.triad,
            amplitude: d.amplitude,
            shape,
        })
    }
}

impl Disturbance {
    /// The disturbance at scenario time `t_s`.
    pub fn at(&self, t_s: f64) -> imu_model::Vec3 {
        let s = match self.shape {
            DisturbanceShape::Sine {
                frequency_hz,
                phase_deg,
            } => (std::f64::consts::TAU * frequency_hz * t_s + phase_deg.to_radians()).sin(),
            DisturbanceShape::Step { at_s } => f64::from(u8::from(t_s >= at_s)),
        };
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
        /// The part of a labelled session this hold belongs to (`imu-sim --export-parts`
        /// writes only the samples of parts, each part's run of segments as one).
        #[serde(default)]
        part: Option<String>,
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
        /// A hand's turn wobbles: its first half is about `axis` tipped by this many degrees
        /// towards the next sensor axis (x to y, y to z, z to x), its second half tipped as far
        /// away, so gravity moves in the sensor frame (cones round the tipped axis) while the
        /// rate integrated over the turn stays about `axis` (but for `1 - cos(wobble)` of it).
        #[serde(rename = "wobble-deg", default)]
        wobble_deg: f64,
        /// The part of a labelled session this turn belongs to (as for `static`).
        #[serde(default)]
        part: Option<String>,
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
    /// Switches the device to `protocol` (the command line's `--protocol`) and checks the
    /// scenario again (a MIP device needs a rate its base rate divides into).
    pub fn set_protocol(
        &mut self,
        protocol: DeviceProtocol,
        file: &str,
    ) -> Result<(), ScenarioError> {
        self.device.protocol = protocol;
        self.validate(file)
    }

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
}

#[cfg(test)]
mod tests;
