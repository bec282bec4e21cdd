//! The `[ros2]` section: domain, namespace, node, topic names, QoS and the queue to the DDS
//! thread. Topic names follow ROS 2's rules: a relative name (`imu/data`) is put in the
//! namespace, an absolute one (`/diagnostics`) is not; an empty name turns that topic off.

use std::net::IpAddr;

use serde::{Deserialize, Serialize};

/// The QoS profile of every imud writer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ros2Qos {
    /// ROS 2's sensor-data profile (`rmw_qos_profile_sensor_data`): best effort, keep last,
    /// volatile. A reliable reader does not match it (and receives nothing).
    SensorData,
    /// Reliable, keep last `depth`, volatile: lost packets are resent to readers that keep up;
    /// matches reliable and best-effort readers. Never blocks the daemon (keep last).
    Reliable,
}

/// Topic names; relative ones are put in the namespace, an empty one is not published.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct Ros2Topics {
    /// Corrected samples, `sensor_msgs/msg/Imu` (the MCAP `/imu/data`).
    pub imu: String,
    /// Uncalibrated samples in physical units (GainScales only), `sensor_msgs/msg/Imu`.
    pub imu_raw: String,
    /// Corrected magnetic field, `sensor_msgs/msg/MagneticField` (tesla).
    pub mag: String,
    /// Device temperature readings, `sensor_msgs/msg/Temperature`.
    pub temperature: String,
    /// The daemon's status, `diagnostic_msgs/msg/DiagnosticArray`.
    pub diagnostics: String,
}

impl Default for Ros2Topics {
    fn default() -> Self {
        Self {
            imu: "imu/data".into(),
            imu_raw: "imu/data_raw".into(),
            mag: "imu/mag".into(),
            temperature: "imu/temperature".into(),
            diagnostics: "/diagnostics".into(),
        }
    }
}

/// ROS 2 output over DDS.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct Ros2Config {
    /// Publish the topics (also `--ros2`).
    pub enabled: bool,
    /// DDS domain, `ROS_DOMAIN_ID` of the ROS 2 side (0 to 232).
    pub domain_id: u16,
    /// Namespace of the relative topic names, e.g. `/robot1` (empty: none).
    pub namespace: String,
    /// Node name: the `name` of the diagnostic status (`<node>: <instance>`).
    pub node: String,
    /// `header.frame_id` of the messages; absent: `log.frame-id`, as in the MCAP log.
    pub frame_id: Option<String>,
    /// QoS profile of every writer.
    pub qos: Ros2Qos,
    /// History depth of every writer (keep last): the samples a writer holds for sending. Its
    /// thread sends them a little later; when the host delays that thread by more than `depth`
    /// samples the oldest are lost, so this is deeper than ROS 2's sensor-data 5 (which is what
    /// a reader asks for and does not have to match).
    pub depth: u16,
    /// Messages queued for the DDS thread before new ones are dropped (and counted).
    pub queue_capacity: usize,
    /// Local addresses DDS may use for multicast and advertise (empty: every interface), e.g.
    /// `["127.0.0.1"]` to keep everything on this host.
    pub interfaces: Vec<IpAddr>,
    /// Topic names.
    pub topics: Ros2Topics,
}

impl Default for Ros2Config {
    fn default() -> Self {
        Self {
            enabled: false,
            domain_id: 0,
            namespace: String::new(),
            node: "imud".into(),
            frame_id: None,
            qos: Ros2Qos::SensorData,
            depth: 1000,
            queue_capacity: 4096,
            interfaces: Vec::new(),
            topics: Ros2Topics::default(),
        }
    }
}

/// The largest domain id whose RTPS ports fit in 16 bits with the default port mapping.
pub const MAX_DOMAIN_ID: u16 = 232;

impl Ros2Config {
    /// The first problem of the section, as (key, message).
    pub fn problem(&self) -> Option<(&'static str, String)> {
        if self.domain_id > MAX_DOMAIN_ID {
            return Some((
                "ros2.domain-id",
                format!(
                    "{} is above {MAX_DOMAIN_ID}, the largest DDS domain id ROS 2 can use",
                    self.domain_id
                ),
            ));
        }
        if !self.namespace.is_empty()
            && let Err(why) = check_name(self.namespace.trim_start_matches('/'))
        {
            return Some(("ros2.namespace", why));
        }
        if let Err(why) = check_token(&self.node) {
            return Some(("ros2.node", why));
        }
        if self.depth == 0 {
            return Some(("ros2.depth", "must be at least 1".into()));
        }
        if self.queue_capacity == 0 {
            return Some(("ros2.queue-capacity", "must be at least 1".into()));
        }
        let t = &self.topics;
        for (key, name) in [
            ("ros2.topics.imu", &t.imu),
            ("ros2.topics.imu-raw", &t.imu_raw),
            ("ros2.topics.mag", &t.mag),
            ("ros2.topics.temperature", &t.temperature),
            ("ros2.topics.diagnostics", &t.diagnostics),
        ] {
            if !name.is_empty()
                && let Err(why) = check_name(name.strip_prefix('/').unwrap_or(name))
            {
                return Some((key, why));
            }
        }
        None
    }

    /// The DDS topic of a ROS 2 topic name: `rt` + the fully qualified name
    /// (`imu/data` in namespace `/robot1` is `rt/robot1/imu/data`); `None` for an empty name.
    pub fn dds_topic(&self, name: &str) -> Option<String> {
        if name.is_empty() {
            return None;
        }
        let ns = self.namespace.trim_matches('/');
        Some(match name.strip_prefix('/') {
            Some(absolute) => format!("rt/{absolute}"),
            None if ns.is_empty() => format!("rt/{name}"),
            None => format!("rt/{ns}/{name}"),
        })
    }
}

/// Checks a topic name as a user writes it: absolute (`/camera/imu`) or relative (`imu/data`).
pub(crate) fn check_topic(name: &str) -> Result<(), String> {
    check_name(name.strip_prefix('/').unwrap_or(name))
}

/// Checks a ROS 2 name without its leading `/`: tokens of letters, digits and `_` separated by
/// single `/`, none starting with a digit.
fn check_name(name: &str) -> Result<(), String> {
    if name.is_empty() {
        return Err("a name needs at least one token".into());
    }
    for token in name.split('/') {
        check_token(token).map_err(|why| format!("{name:?}: {why}"))?;
    }
    Ok(())
}

/// One token of a ROS 2 name (a node name is one token).
fn check_token(token: &str) -> Result<(), String> {
    let ok_chars = token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    match token.chars().next() {
        None => Err("empty name part (a doubled or trailing `/`)".into()),
        Some(c) if c.is_ascii_digit() => Err(format!("{token:?} starts with a digit")),
        Some(_) if !ok_chars => Err(format!(
            "{token:?} may hold only letters, digits and `_` (ROS 2 name rules)"
        )),
        Some(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;

    #[test]
    fn topic_names_are_put_in_the_namespace_unless_absolute() {
        let mut c = Ros2Config::default();
        assert_eq!(c.dds_topic("imu/data").unwrap(), "rt/imu/data");
        assert_eq!(c.dds_topic("/diagnostics").unwrap(), "rt/diagnostics");
        c.namespace = "/robot1".into();
        assert_eq!(c.dds_topic("imu/data").unwrap(), "rt/robot1/imu/data");
        assert_eq!(c.dds_topic("/diagnostics").unwrap(), "rt/diagnostics");
        assert_eq!(c.dds_topic(""), None);
    }

    #[test]
    fn bad_values_name_their_key_and_line() {
        let e = |text: &str| {
            Config::from_toml_str(text, "r.toml")
                .unwrap_err()
                .to_string()
        };
        let m = e("[ros2]\nenabled = true\ndomain-id = 233\n");
        assert!(m.starts_with("r.toml:3: `ros2.domain-id`"), "{m}");
        let m = e("[ros2]\nnamespace = \"/robot 1\"\n");
        assert!(m.starts_with("r.toml:2: `ros2.namespace`"), "{m}");
        let m = e("[ros2.topics]\nimu = \"imu//data\"\n");
        assert!(
            m.contains("`ros2.topics.imu`") && m.contains("doubled"),
            "{m}"
        );
        let m = e("[ros2]\nnode = \"9imud\"\n");
        assert!(m.contains("`ros2.node`") && m.contains("digit"), "{m}");
        let m = e("[ros2]\nqos = \"fast\"\n");
        assert!(m.starts_with("r.toml:2:"), "{m}");
        let m = e("[ros2]\ninterfaces = [\"localhost\"]\n");
        assert!(m.starts_with("r.toml:2:"), "{m}");
    }

    #[test]
    fn a_valid_section_parses() {
        let c = Config::from_toml_str(
            "[ros2]\nenabled = true\ndomain-id = 7\nnamespace = \"/robot1\"\nqos = \"reliable\"\n\
             interfaces = [\"127.0.0.1\"]\n[ros2.topics]\nimu-raw = \"\"\n",
            "ok.toml",
        )
        .unwrap();
        assert!(c.ros2.enabled);
        assert_eq!(c.ros2.qos, Ros2Qos::Reliable);
        assert_eq!(c.ros2.interfaces, ["127.0.0.1".parse::<IpAddr>().unwrap()]);
        assert_eq!(c.ros2.dds_topic(&c.ros2.topics.imu_raw), None);
    }
}
