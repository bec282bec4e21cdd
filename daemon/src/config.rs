//! imud's configuration: a strict TOML file layered over built-in defaults, then command-line
//! flags on top.
//!
//! Which file: `--config FILE`, else `$IMUD_CONFIG`, else `/etc/imud/imud.toml` if it exists, else
//! none (built-in defaults). Every key is kebab-case; an unknown key, a wrong type or an
//! impossible value is an error naming the file, the line and the key. `config/imud.toml` in the
//! repository documents every key with its default and is parsed by a test.

use std::path::{Path, PathBuf};

use imu_analysis::health::still::StillOptions;
use imu_analysis::health::{CheckOptions, Gravity};
use serde::{Deserialize, Serialize};

/// Errors loading the configuration.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{file}: cannot read the configuration")]
    Io {
        /// The file.
        file: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid for this schema.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A value is out of range.
    #[error("{file}:{line}: `{key}`: {message}")]
    Invalid {
        /// The file (or `command line`).
        file: String,
        /// 1-based line of the key (0 when it came from the command line or a default).
        line: usize,
        /// The dotted key, e.g. `device.baud`.
        key: String,
        /// What is wrong and what to do.
        message: String,
    },
}

/// The whole configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct Config {
    /// Instance name: shared-memory services are `imud/<name>/...`, log files start with it.
    pub name: String,
    /// The serial device and how to talk to it.
    pub device: DeviceConfig,
    /// A ROS 2 topic taken as the device instead of the serial unit.
    pub input: InputConfig,
    /// The calibration applied in real time.
    pub calibration: CalibrationConfig,
    /// MCAP logging.
    pub log: LogConfig,
    /// Shared-memory publishing.
    pub publish: PublishConfig,
    /// Live calibration health.
    pub health: HealthConfig,
    /// ROS 2 topics over DDS (off by default).
    pub ros2: Ros2Config,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            name: "default".into(),
            device: DeviceConfig::default(),
            input: InputConfig::default(),
            calibration: CalibrationConfig::default(),
            log: LogConfig::default(),
            publish: PublishConfig::default(),
            health: HealthConfig::default(),
            ros2: Ros2Config::default(),
        }
    }
}

/// How samples are requested from the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AcquisitionMode {
    /// Continuous mode (`10 00 <cmd>`): the device streams at its own rate; temperature is read
    /// at start-up only (the device sends nothing else while streaming).
    Continuous,
    /// The host polls each sample at `poll-rate-hz` and interleaves temperature reads at
    /// `temperature-rate-hz` (needed for thermal tests).
    Polled,
}

/// Which data reply to acquire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SampleCommand {
    /// 0x01 raw ADC bits: what the paper calibrates from.
    RawBits,
    /// 0x02 gyro-stabilized vectors (scaled).
    StabilizedVectors,
    /// 0x03 instantaneous vectors (scaled).
    InstantaneousVectors,
}

/// GainScale words used when the device does not answer the EEPROM read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct GainConfig {
    /// Accelerometer GainScale.
    pub accel: u16,
    /// Gyro GainScale.
    pub gyro: u16,
    /// Magnetometer GainScale.
    pub mag: u16,
}

/// The serial device.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct DeviceConfig {
    /// Device path, e.g. `/dev/ttyUSB0` or a udev link `/dev/imu0`.
    pub path: PathBuf,
    /// The protocol the device speaks; none: probed at each start-up (`drivers/probe.rs`).
    #[serde(with = "protocol_option", skip_serializing_if = "Option::is_none")]
    pub protocol: Option<imu_proto::DeviceProtocol>,
    /// MIP: the data rate to configure, Hz (the unit's base rate / a whole decimation); Xsens:
    /// the output rate, a whole number of Hz; none: the rate the unit is set to.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rate_hz: Option<f64>,
    /// Serial line rate, bits/s (38400 is the factory default).
    pub baud: u32,
    /// Configure the unit at start-up; false (`--passive`): send it nothing and take the
    /// stream as it is (`drivers/`: each driver's passive mode).
    pub configure: bool,
    /// Continuous or polled acquisition.
    pub mode: AcquisitionMode,
    /// Which data reply to acquire.
    pub command: SampleCommand,
    /// Poll rate in polled mode, Hz.
    pub poll_rate_hz: f64,
    /// Temperature reads per second in polled mode (at least 1 for thermal tests).
    pub temperature_rate_hz: f64,
    /// Nominal timer tick period, s (6.5536 ms on most units; 10 ms on reprogrammed ones).
    pub tick_period_s: f64,
    /// GainScales used only if the device's EEPROM cannot be read (always reported loudly).
    pub fallback_gains: GainConfig,
    /// How long to wait for each start-up reply, s.
    pub reply_timeout_s: f64,
    /// First reconnect delay after the device is lost, s (doubles up to `reconnect-max-s`).
    pub reconnect_min_s: f64,
    /// Longest reconnect delay, s.
    pub reconnect_max_s: f64,
    /// No data for this long while streaming means the device is lost, s.
    pub silence_timeout_s: f64,
    /// Where sample stamps come from.
    pub time_source: TimeSource,
}

/// `device.time-source`: where sample stamps come from (`pipeline`, `clock/`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TimeSource {
    /// Each frame's host receive time as is, monotonic and wall (what naive drivers do: the
    /// link's latency and the host's wake-ups are in the stamps).
    Host,
    /// The device's clock mapped onto the host clock by the clock fit.
    #[default]
    Device,
    /// Wall stamps follow the unit's valid GNSS time (UTC), fitted against the device clock
    /// and held over on it while GNSS time is invalid or absent; monotonic stamps as `device`.
    Gnss,
}

impl TimeSource {
    /// The name in the configuration.
    pub fn name(self) -> &'static str {
        match self {
            TimeSource::Host => "host",
            TimeSource::Device => "device",
            TimeSource::Gnss => "gnss",
        }
    }

    /// The [`imu_bus::sample::time_source`] code of the status.
    pub fn code(self) -> u8 {
        use imu_bus::sample::time_source;
        match self {
            TimeSource::Host => time_source::HOST,
            TimeSource::Device => time_source::DEVICE,
            TimeSource::Gnss => time_source::GNSS,
        }
    }
}

impl std::str::FromStr for TimeSource {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [TimeSource::Host, TimeSource::Device, TimeSource::Gnss]
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| format!("unknown time source `{s}` (host, device or gnss)"))
    }
}

impl Default for DeviceConfig {
    fn default() -> Self {
        let fb = imu_proto::GainScales::DEFAULT_FALLBACK;
        Self {
            path: PathBuf::from("/dev/ttyUSB0"),
            protocol: None,
            rate_hz: None,
            baud: 38_400,
            configure: true,
            mode: AcquisitionMode::Continuous,
            command: SampleCommand::RawBits,
            poll_rate_hz: 100.0,
            temperature_rate_hz: 1.0,
            tick_period_s: imu_proto::ticks::DEFAULT_TICK_PERIOD_S,
            fallback_gains: GainConfig {
                accel: fb.accel,
                gyro: fb.gyro,
                mag: fb.mag,
            },
            reply_timeout_s: 1.0,
            reconnect_min_s: 0.5,
            reconnect_max_s: 10.0,
            silence_timeout_s: 2.0,
            time_source: TimeSource::Device,
        }
    }
}

/// `device.protocol` as its name (`"3dm-gx1"`, `"mip"`, `"xsens"`), absent when probed.
mod protocol_option {
    use imu_proto::DeviceProtocol;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(p: &Option<DeviceProtocol>, s: S) -> Result<S::Ok, S::Error> {
        match p {
            Some(p) => s.serialize_str(p.name()),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<DeviceProtocol>, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map(Some).map_err(serde::de::Error::custom)
    }
}

/// Where the samples come from when it is not the serial unit of `[device]`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct InputConfig {
    /// A ROS 2 `sensor_msgs/msg/Imu` topic (e.g. `/camera/imu`) subscribed to over DDS on
    /// `ros2.domain-id` and taken as the device (also `--ros2-input`); a relative name is put
    /// in `ros2.namespace`. `[device]`'s path, protocol and line settings then do not apply;
    /// its silence and reconnect timings do.
    pub ros2_topic: Option<String>,
}

impl InputConfig {
    /// The first problem of the section given the ROS 2 output's topics, as (key, message).
    fn problem(&self, ros2: &Ros2Config) -> Option<(&'static str, String)> {
        let topic = self.ros2_topic.as_deref()?;
        const KEY: &str = "input.ros2-topic";
        if let Err(why) = crate::ros2::config::check_topic(topic) {
            return Some((KEY, why));
        }
        if !ros2.enabled {
            return None;
        }
        // imud's own sensor_msgs/Imu topics: reading one back would feed the corrected
        // stream into itself.
        let t = &ros2.topics;
        let input = ros2.dds_topic(topic);
        for (key, name) in [
            ("ros2.topics.imu", &t.imu),
            ("ros2.topics.imu-raw", &t.imu_raw),
        ] {
            if input.is_some() && ros2.dds_topic(name) == input {
                return Some((
                    KEY,
                    format!(
                        "{topic:?} is imud's own ROS 2 output topic ({key} = {name:?}, DDS {}): \
                         reading it back would feed imud's output into itself; rename that \
                         output topic or subscribe to the driver's topic",
                        input.unwrap_or_default()
                    ),
                ));
            }
        }
        None
    }
}

/// The calibration applied in real time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct CalibrationConfig {
    /// Calibration file (imu-model TOML). Without one the corrected stream uses the device's
    /// GainScales only and says so in its flags.
    pub path: Option<PathBuf>,
    /// Reload when the file changes (it is always reloaded on SIGHUP).
    pub watch: bool,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            path: None,
            watch: true,
        }
    }
}

/// Live calibration health: the calibration held against gravity and Earth's rate whenever the
/// unit is still (see `health.rs`, over `imu_analysis::health`). The defaults are
/// `imu_analysis::health::CheckOptions`'s (the still detector's, the offline segmentation's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct HealthConfig {
    /// Watch the calibration's health.
    pub enabled: bool,
    /// Latitude, deg: normal gravity and the vertical part of Earth's rate. Without it (and
    /// without `gravity-m-s2`) gravity is learned from the first still windows, so only changes
    /// are seen.
    pub latitude_deg: Option<f64>,
    /// Height above the ellipsoid, m (normal gravity's free-air term).
    pub height_m: f64,
    /// Local gravity, m/s^2, when known better than normal gravity (a survey, a gravimeter).
    pub gravity_m_s2: Option<f64>,
    /// Block over which stillness is judged, s.
    pub block_s: f64,
    /// A block is quiet below this many times the noise floor.
    pub threshold_factor: f64,
    /// Quantile of the recent blocks' deviations taken as the noise floor.
    pub floor_quantile: f64,
    /// Shortest still window, s (after one block is trimmed at each end next to motion).
    pub min_still_s: f64,
    /// Longest still window, s: a long rest is tested every this many seconds.
    pub max_window_s: f64,
    /// A quiet window whose mean rate is this far from the reading at rest is a steady
    /// rotation, not a rest, rad/s.
    pub plateau_min_rate_rad_s: f64,
    /// Largest mean rate that can be the gyro's reading at rest, rad/s.
    pub max_rest_rate_rad_s: f64,
    /// p-value below which a still window rejects the calibration: the false-alarm rate per
    /// still window.
    pub false_alarm_p: f64,
    /// Apply a stale triad's estimated bias offset to the corrected stream (logged and
    /// recorded; off by default).
    pub track_bias: bool,
    /// Largest accel bias offset bias tracking applies, m/s^2.
    pub track_bias_max_m_s2: f64,
    /// Largest gyro bias offset bias tracking applies, rad/s.
    pub track_bias_max_rad_s: f64,
}

impl Default for HealthConfig {
    /// The defaults of `imu_analysis::health::CheckOptions` (their one home), health on and
    /// bias tracking off.
    fn default() -> Self {
        let o = CheckOptions::default();
        let gravity_m_s2 = match o.gravity {
            Gravity::Known(g) => Some(g),
            Gravity::Normal | Gravity::Learned => None,
        };
        Self {
            enabled: true,
            latitude_deg: o.latitude_deg,
            height_m: o.height_m,
            gravity_m_s2,
            block_s: o.still.block_s,
            threshold_factor: o.still.threshold_factor,
            floor_quantile: o.still.floor_quantile,
            min_still_s: o.still.min_still_s,
            max_window_s: o.still.max_window_s,
            plateau_min_rate_rad_s: o.still.plateau_min_rate_rad_s,
            max_rest_rate_rad_s: o.still.max_rest_rate_rad_s,
            false_alarm_p: o.false_alarm_p,
            track_bias: false,
            track_bias_max_m_s2: 0.5,
            track_bias_max_rad_s: 0.05,
        }
    }
}

impl HealthConfig {
    /// The health checks' options these settings give (`imu_analysis::health`).
    pub fn check_options(&self) -> CheckOptions {
        CheckOptions {
            still: StillOptions {
                block_s: self.block_s,
                threshold_factor: self.threshold_factor,
                floor_quantile: self.floor_quantile,
                min_still_s: self.min_still_s,
                max_window_s: self.max_window_s,
                plateau_min_rate_rad_s: self.plateau_min_rate_rad_s,
                max_rest_rate_rad_s: self.max_rest_rate_rad_s,
            },
            latitude_deg: self.latitude_deg,
            height_m: self.height_m,
            gravity: Gravity::from_settings(self.gravity_m_s2, self.latitude_deg),
            false_alarm_p: self.false_alarm_p,
        }
    }
}

/// MCAP logging.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct LogConfig {
    /// Log every frame to MCAP.
    pub enabled: bool,
    /// Directory for the MCAP files (created if missing).
    pub dir: PathBuf,
    /// Start a new file after this many MiB (0: never).
    pub rotate_size_mib: u64,
    /// Start a new file after this many seconds (0: never).
    pub rotate_interval_s: f64,
    /// Records queued for the writer thread before new ones are dropped (and counted). A
    /// sample with its frame is one record (about 400 bytes a slot, allocated at start).
    pub queue_capacity: usize,
    /// `frame_id` of the ROS messages.
    pub frame_id: String,
}

impl Default for LogConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            dir: PathBuf::from("imud-logs"),
            rotate_size_mib: 512,
            rotate_interval_s: 3600.0,
            queue_capacity: 32_768,
            frame_id: "imu_link".into(),
        }
    }
}

/// Shared-memory publishing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct PublishConfig {
    /// Publish over iceoryx2.
    pub enabled: bool,
    /// Samples buffered per subscriber (older ones are overwritten for a slow subscriber).
    pub subscriber_buffer: usize,
    /// Samples a late subscriber receives on connecting.
    pub history: usize,
    /// Most subscribers per service.
    pub max_subscribers: usize,
    /// Status publication interval, s.
    pub status_interval_s: f64,
    /// The readers' socket: imud's streams for processes of other users (iceoryx2's segments
    /// are owner-only). Served when this or `group` is set; default path
    /// `/run/imud/<name>/readers.sock`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub readers_socket: Option<std::path::PathBuf>,
    /// The group whose members may connect to the readers' socket (mode 0660); unset: this
    /// user only (0600). imud's user must be a member.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

impl PublishConfig {
    /// The readers' socket path for instance `name`, when one is to be served.
    pub fn readers_socket_path(&self, name: &str) -> Option<std::path::PathBuf> {
        match (&self.readers_socket, &self.group) {
            (Some(path), _) => Some(path.clone()),
            (None, Some(_)) => Some(imu_bus::readers::default_socket_path(name)),
            (None, None) => None,
        }
    }
}

impl Default for PublishConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            subscriber_buffer: 256,
            history: 1,
            max_subscribers: 16,
            status_interval_s: 1.0,
            readers_socket: None,
            group: None,
        }
    }
}

pub use crate::ros2::config::{Ros2Config, Ros2Qos, Ros2Topics};

/// Where a configuration came from (for messages).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Source {
    /// The file name, or `built-in defaults`.
    pub file: String,
    /// Its text (empty for defaults).
    pub text: String,
}

impl Config {
    /// Parses a configuration file's text over the built-in defaults.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, ConfigError> {
        let config: Config = toml::from_str(text).map_err(|e| {
            let (line, column) = e
                .span()
                .map_or((1, 1), |s| imu_model::line_col(text, s.start));
            ConfigError::Parse {
                file: file.to_string(),
                line,
                column,
                message: e.message().to_string(),
            }
        })?;
        config.validate(&Source {
            file: file.to_string(),
            text: text.to_string(),
        })?;
        Ok(config)
    }

    /// Finds and loads the configuration file (see the module docs), or the defaults.
    pub fn load(explicit: Option<&Path>) -> Result<(Self, Source), ConfigError> {
        let env = std::env::var_os("IMUD_CONFIG").map(PathBuf::from);
        let etc = PathBuf::from("/etc/imud/imud.toml");
        let path = match (explicit, env) {
            (Some(p), _) => Some(p.to_path_buf()),
            (None, Some(p)) => Some(p),
            (None, None) => etc.exists().then_some(etc),
        };
        let Some(path) = path else {
            return Ok((
                Self::default(),
                Source {
                    file: "built-in defaults".into(),
                    text: String::new(),
                },
            ));
        };
        let file = path.display().to_string();
        let text = std::fs::read_to_string(&path).map_err(|source| ConfigError::Io {
            file: file.clone(),
            source,
        })?;
        let config = Self::from_toml_str(&text, &file)?;
        Ok((config, Source { file, text }))
    }

    /// What the samples come from, for messages: the ROS 2 input's topic or the device path.
    pub fn input_name(&self) -> String {
        match &self.input.ros2_topic {
            Some(topic) => format!("ROS 2 topic {topic}"),
            None => self.device.path.display().to_string(),
        }
    }

    /// Checks values that parse but make no sense.
    pub fn validate(&self, source: &Source) -> Result<(), ConfigError> {
        let problem = self
            .name_problem()
            .or_else(|| self.device_problem())
            .or_else(|| self.input.problem(&self.ros2))
            .or_else(|| self.log_publish_problem())
            .or_else(|| self.health_problem())
            .or_else(|| self.ros2.problem());
        match problem {
            None => Ok(()),
            Some((key, message)) => Err(ConfigError::Invalid {
                file: source.file.clone(),
                line: imu_model::line_of_key(&source.text, key).unwrap_or(0),
                key: key.to_string(),
                message,
            }),
        }
    }

    /// The instance name's problem, as (key, message).
    fn name_problem(&self) -> Option<(&'static str, String)> {
        // The same rule as every client that opens the instance's services (imu-echo).
        if let Err(e) = imu_bus::shm::validate_instance_name(&self.name) {
            return Some((
                "name",
                format!("{e} (it names shared-memory services and files)"),
            ));
        }
        None
    }

    /// The first problem of the `[device]` settings (and the status interval), as (key, message).
    fn device_problem(&self) -> Option<(&'static str, String)> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let d = &self.device;
        if !(300..=4_000_000).contains(&d.baud) {
            return Some((
                "device.baud",
                format!(
                    "{} is not a serial line rate (38400 is the 3DM-GX1 default)",
                    d.baud
                ),
            ));
        }
        if !positive(d.poll_rate_hz) || d.poll_rate_hz > 10_000.0 {
            return Some((
                "device.poll-rate-hz",
                format!("{} Hz must be in (0, 10000]", d.poll_rate_hz),
            ));
        }
        if !(d.temperature_rate_hz.is_finite() && d.temperature_rate_hz >= 0.0)
            || d.temperature_rate_hz > d.poll_rate_hz
        {
            return Some((
                "device.temperature-rate-hz",
                format!(
                    "{} Hz must be >= 0 and at most poll-rate-hz",
                    d.temperature_rate_hz
                ),
            ));
        }
        for (key, v) in [
            ("device.tick-period-s", d.tick_period_s),
            ("device.reply-timeout-s", d.reply_timeout_s),
            ("device.reconnect-min-s", d.reconnect_min_s),
            ("device.reconnect-max-s", d.reconnect_max_s),
            ("device.silence-timeout-s", d.silence_timeout_s),
            ("publish.status-interval-s", self.publish.status_interval_s),
        ] {
            if !positive(v) {
                return Some((key, format!("{v} must be a positive number of seconds")));
            }
        }
        if let Some(problem) = crate::drivers::config_problem(d) {
            return Some(problem);
        }
        if let Some(r) = d.rate_hz
            && !(positive(r) && r <= 10_000.0)
        {
            return Some(("device.rate-hz", format!("{r} Hz must be in (0, 10000]")));
        }
        if d.reconnect_max_s < d.reconnect_min_s {
            return Some((
                "device.reconnect-max-s",
                "must be at least reconnect-min-s".into(),
            ));
        }
        let g = d.fallback_gains;
        if g.accel == 0 || g.gyro == 0 || g.mag == 0 {
            return Some((
                "device.fallback-gains",
                "GainScale words must be non-zero".into(),
            ));
        }
        None
    }

    /// The first problem of the `[log]` and `[publish]` settings, as (key, message).
    fn log_publish_problem(&self) -> Option<(&'static str, String)> {
        if self.log.queue_capacity == 0 {
            return Some(("log.queue-capacity", "must be at least 1".into()));
        }
        if !(self.log.rotate_interval_s.is_finite() && self.log.rotate_interval_s >= 0.0) {
            return Some(("log.rotate-interval-s", "must be >= 0 (0: never)".into()));
        }
        if self.publish.subscriber_buffer == 0 || self.publish.max_subscribers == 0 {
            return Some((
                "publish.subscriber-buffer",
                "buffers and subscriber counts must be at least 1".into(),
            ));
        }
        None
    }

    /// The first problem of the `[health]` settings, as (key, message).
    fn health_problem(&self) -> Option<(&'static str, String)> {
        let h = &self.health;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if let Some(lat) = h.latitude_deg
            && !(lat.is_finite() && (-90.0..=90.0).contains(&lat))
        {
            return Some(("health.latitude-deg", format!("{lat} must be in [-90, 90]")));
        }
        if let Some(g) = h.gravity_m_s2
            && !(g.is_finite() && (9.7..=9.9).contains(&g))
        {
            return Some((
                "health.gravity-m-s2",
                format!("{g} m/s^2 is not Earth's gravity (9.78 to 9.83)"),
            ));
        }
        for (key, v) in [
            ("health.block-s", h.block_s),
            ("health.threshold-factor", h.threshold_factor),
            ("health.min-still-s", h.min_still_s),
            ("health.max-window-s", h.max_window_s),
            ("health.plateau-min-rate-rad-s", h.plateau_min_rate_rad_s),
            ("health.max-rest-rate-rad-s", h.max_rest_rate_rad_s),
            ("health.track-bias-max-m-s2", h.track_bias_max_m_s2),
            ("health.track-bias-max-rad-s", h.track_bias_max_rad_s),
        ] {
            if !positive(v) {
                return Some((key, format!("{v} must be a positive number")));
            }
        }
        if !(h.floor_quantile > 0.0 && h.floor_quantile < 1.0) {
            return Some(("health.floor-quantile", "must be in (0, 1)".into()));
        }
        if !(h.false_alarm_p > 0.0 && h.false_alarm_p < 0.5) {
            return Some((
                "health.false-alarm-p",
                "must be in (0, 0.5): the p-value of one still window".into(),
            ));
        }
        if h.max_window_s < h.min_still_s {
            return Some(("health.max-window-s", "must be at least min-still-s".into()));
        }
        None
    }

    /// The effective configuration as TOML (for `imud --print-config`).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("the configuration always serializes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn documented_default_file_equals_the_built_in_defaults() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../config/imud.toml");
        let text = std::fs::read_to_string(path).unwrap();
        let parsed = Config::from_toml_str(&text, path).unwrap();
        assert_eq!(
            parsed,
            Config::default(),
            "config/imud.toml must document the real defaults"
        );
    }

    #[test]
    fn the_readers_socket_is_served_when_a_path_or_a_group_is_set() {
        let path = |text: &str| {
            Config::from_toml_str(text, "r.toml")
                .unwrap()
                .publish
                .readers_socket_path("imu0")
        };
        assert_eq!(path(""), None);
        assert_eq!(
            path("[publish]\ngroup = \"imud-readers\"\n"),
            Some(std::path::PathBuf::from("/run/imud/imu0/readers.sock"))
        );
        assert_eq!(
            path("[publish]\nreaders-socket = \"/srv/r.sock\"\n"),
            Some(std::path::PathBuf::from("/srv/r.sock"))
        );
        // Both settings survive --print-config's round trip.
        let c = Config::from_toml_str(
            "[publish]\nreaders-socket = \"/srv/r.sock\"\ngroup = \"g\"\n",
            "r.toml",
        )
        .unwrap();
        assert_eq!(Config::from_toml_str(&c.to_toml(), "again").unwrap(), c);
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let e = Config::from_toml_str("name = \"a\"\n[device]\nbaud = 38400\nbuad = 1\n", "x.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.toml:4:"), "{e}");
        assert!(e.contains("buad"), "{e}");
    }

    #[test]
    fn bad_value_names_file_line_and_key() {
        let e = Config::from_toml_str("[device]\npath = \"/dev/x\"\nbaud = 12\n", "y.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e.split(':').take(2).collect::<Vec<_>>(),
            ["y.toml", "3"],
            "{e}"
        );
        assert!(e.contains("device.baud"), "{e}");
        let e = Config::from_toml_str("[device]\nmode = \"sometimes\"\n", "z.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("z.toml:2:"), "{e}");
    }

    #[test]
    fn instance_names_follow_the_shared_memory_rule() {
        let parse = |name: &str| Config::from_toml_str(&format!("name = \"{name}\"\n"), "n.toml");
        // A dot is as valid for the daemon as for imu-echo; a slash is not for either.
        assert!(parse("imu.front_0").is_ok());
        for bad in ["", "a/b", "a b", &"x".repeat(65)] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains("`name`"), "{e}");
            assert!(imu_bus::shm::validate_instance_name(bad).is_err());
        }
    }

    #[test]
    fn a_ros2_input_is_refused_when_it_is_imuds_own_output_topic() {
        let parse = |text: &str| Config::from_toml_str(text, "i.toml");
        let c = parse("[input]\nros2-topic = \"/camera/imu\"\n").unwrap();
        assert_eq!(c.input.ros2_topic.as_deref(), Some("/camera/imu"));
        assert_eq!(Config::from_toml_str(&c.to_toml(), "printed").unwrap(), c);
        // Without the output there is nothing to feed back.
        assert!(parse("[input]\nros2-topic = \"/imu/data_raw\"\n").is_ok());
        for (input, ros2) in [
            ("/imu/data_raw", ""),
            ("imu/data", ""),
            ("/robot1/imu/data", "namespace = \"/robot1\"\n"),
            ("/mine", "[ros2.topics]\nimu = \"/mine\"\n"),
        ] {
            let text = format!("[input]\nros2-topic = \"{input}\"\n[ros2]\nenabled = true\n{ros2}");
            let e = parse(&text).unwrap_err().to_string();
            assert!(e.starts_with("i.toml:2: `input.ros2-topic`"), "{e}");
            assert!(e.contains("imud's own ROS 2 output topic"), "{e}");
        }
        // In another namespace the same name is another topic.
        let ok = "[input]\nros2-topic = \"/imu/data_raw\"\n[ros2]\nenabled = true\n\
                  namespace = \"/imud\"\n";
        assert!(parse(ok).is_ok());
        let e = parse("[input]\nros2-topic = \"/camera//imu\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`input.ros2-topic`") && e.contains("doubled"),
            "{e}"
        );
    }

    #[test]
    fn time_source_parses_and_a_bad_one_names_file_and_line() {
        let c = Config::from_toml_str("[device]\ntime-source = \"gnss\"\n", "t.toml").unwrap();
        assert_eq!(c.device.time_source, TimeSource::Gnss);
        assert_eq!(Config::from_toml_str(&c.to_toml(), "printed").unwrap(), c);
        assert_eq!(Config::default().device.time_source, TimeSource::Device);
        let e = Config::from_toml_str("[device]\nbaud = 38400\ntime-source = \"gps\"\n", "t.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.toml:3:"), "{e}");
        assert!(e.contains("gps"), "{e}");
        assert_eq!("host".parse::<TimeSource>(), Ok(TimeSource::Host));
        assert!("utc".parse::<TimeSource>().is_err());
    }

    #[test]
    fn print_config_round_trips() {
        let c = Config::default();
        assert_eq!(Config::from_toml_str(&c.to_toml(), "printed").unwrap(), c);
    }
}
