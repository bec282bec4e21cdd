//! The rosbag2 sqlite3 reader (`imu_rec::ros2::sqlite`): no panic on any file; its report
//! counts what it handed over; decoding the `sensor_msgs/msg/Imu` messages it hands over never
//! panics. SQLite pages are not in file order, so a cut file has no prefix to compare with and
//! the input is the file alone.

use imu_rec::ros2::{Imu, RosMessage};

use super::files::through_file;
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "ros2_db3",
    about: "the rosbag2 sqlite3 reader (imu_rec::ros2::sqlite); seeds by Python rosbags",
    check,
    seeds: None,
    dictionary: &[
        b"SQLite format 3\0",
        b"messages",
        b"topics",
        b"sensor_msgs/msg/Imu",
        b"cdr",
        &[0x0D],
        &[0x05],
        &[0x00, 0x00, 0x00, 0x00],
        &[0xFF, 0xFF, 0xFF, 0xFF],
    ],
    ci_mutations: 20_000,
};

/// Input: the `.db3` file.
fn check(data: &[u8]) {
    through_file("input.db3", data, |path| {
        let mut n = 0u64;
        let read = imu_rec::ros2::sqlite::for_each_message_with_progress(
            path,
            path,
            &mut |_, _| {},
            |topic, _, message| {
                if topic.msg_type == Imu::DEFINITION.type_name {
                    let _ = Imu::from_cdr(message);
                }
                n += 1;
                Ok(())
            },
        );
        match read {
            Ok(report) => assert_eq!(report.n_messages, n, "the report counts"),
            Err(e) => assert!(!e.to_string().is_empty(), "an error says what is wrong"),
        }
    });
}
