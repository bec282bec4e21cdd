//! ROS 1 bags (format 2.0, told by their `#ROSBAG V2.0` line): `sensor_msgs/Imu` and
//! `sensor_msgs/Temperature` connections, each checked once against the layout decoded here
//! (its MD5 sum, else its message definition), read through `imu_rec::ros1` into the shared
//! `collect.rs`. A bag never indexed or cut short is read up to its last complete record and
//! reported as an unfinished MCAP is.

use std::collections::BTreeMap;
use std::path::Path;

use imu_rec::ros1::bag::{self, Connection};
use imu_rec::ros1::{Ros1Message, check_definition};
use imu_rec::ros2::{Imu, Temperature};

use super::collect::{Collector, ReadEnd};
use super::{ImuSeries, InputError, Source};

/// Reads a ROS 1 bag, reporting `(bytes read, file size)` as it goes. `topic` picks the IMU
/// topic as for MCAP.
pub fn read_ros1_bag_with_progress(
    path: &Path,
    source: Source,
    topic: Option<&str>,
    on_progress: &mut dyn FnMut(u64, u64),
) -> Result<ImuSeries, InputError> {
    let mut collect = Collector::new(source, topic);
    // Each connection's definition is checked at its first decoded message.
    let mut checked: BTreeMap<u32, ()> = BTreeMap::new();
    let mut check = |c: &Connection, ok: fn(&str, &str) -> Result<(), String>| {
        if checked.contains_key(&c.id) {
            return Ok(());
        }
        ok(&c.md5sum, &c.message_definition)
            .map_err(|e| format!("connection {} ({}): {e}", c.id, c.msg_type))?;
        checked.insert(c.id, ());
        Ok::<(), String>(())
    };
    let report = bag::for_each_message_with_progress(path, on_progress, |c, _t_ns, data| match c
        .msg_type
        .as_str()
    {
        Imu::TYPE => collect.imu(&c.topic, || {
            check(c, check_definition::<Imu>)?;
            Imu::from_ros1(data).map_err(|e| format!("{}: {e}", Imu::TYPE))
        }),
        Temperature::TYPE => {
            check(c, check_definition::<Temperature>)?;
            let m =
                Temperature::from_ros1(data).map_err(|e| format!("{}: {e}", Temperature::TYPE))?;
            collect.temperature(m.header.stamp.to_ns(), m.temperature);
            Ok(())
        }
        _ => Ok(()),
    })?;
    for c in report.connections.values() {
        if c.msg_type == Imu::TYPE {
            collect.imu_topic(&c.topic);
        }
    }
    let end = ReadEnd {
        stopped_early: report.stopped_early,
        unfinished: report.unfinished,
        imud_file: None,
        calibration: None,
    };
    collect.finish(path, None, end)
}
