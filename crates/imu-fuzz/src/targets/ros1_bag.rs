//! The tolerant ROS 1 bag reader (`imu_rec::ros1::bag`): see `files` for the checks; its report
//! agrees with what it handed over, `Unfinished` is set exactly when the read stopped early, and
//! decoding the `sensor_msgs` messages it hands over never panics.

use imu_rec::ros1::Ros1Message;
use imu_rec::ros2::{Imu, Temperature};

use super::files::{Message, Read, check_cut, through_file};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "ros1_bag",
    about: "the tolerant ROS 1 bag reader (imu_rec::ros1::bag), whole and cut files; seeds by \
            Python rosbags",
    check,
    seeds: None,
    dictionary: &[
        b"#ROSBAG V2.0\n",
        b"op=\x02",
        b"op=\x03",
        b"op=\x05",
        b"op=\x06",
        b"op=\x07",
        b"compression=none",
        b"compression=bz2",
        b"compression=lz4",
        b"conn=",
        b"index_pos=",
        &[0x00, 0x00, 0x00, 0x00],
        &[0xFF, 0xFF, 0xFF, 0x7F],
    ],
    ci_mutations: 20_000,
};

/// Input: `[cut (u16, little-endian), file...]`.
fn check(data: &[u8]) {
    check_cut(data, read);
}

/// Reads a ROS 1 bag's bytes.
pub(crate) fn read(file: &[u8]) -> Read {
    through_file("input.bag", file, |path| {
        let mut messages = Vec::new();
        let outcome = imu_rec::ros1::bag::for_each_message(path, |conn, time_ns, data| {
            if conn.msg_type == Imu::TYPE {
                let _ = Imu::from_ros1(data);
            } else if conn.msg_type == Temperature::TYPE {
                let _ = Temperature::from_ros1(data);
            }
            messages.push(Message {
                topic: conn.topic.clone(),
                msg_type: conn.msg_type.clone(),
                time_ns,
                data: data.to_vec(),
            });
            Ok(())
        });
        let outcome = outcome.map(|r| (r.n_messages, r.stopped_early, r.unfinished.is_some()));
        let outcome = super::files::outcome(outcome, messages.len());
        Read { messages, outcome }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::targets::files::split_cut;

    #[test]
    fn the_committed_bags_read_completely_and_their_cuts_keep_a_prefix() {
        // rosbags wrote 6 samples on /imu/a, /imu/b and /imu/temperature (30 in the last bag).
        let bags = crate::corpus::load(&TARGET.corpus_dir()).unwrap();
        let mut complete = 0;
        for bag in &bags {
            let (cut, file) = split_cut(bag).unwrap();
            let whole = read(file);
            assert_eq!(whole.outcome, Ok(None));
            assert!(
                [18, 90].contains(&whole.messages.len()),
                "{}",
                whole.messages.len()
            );
            complete += 1;
            let part = read(&file[..cut]);
            if cut < file.len() {
                assert!(matches!(part.outcome, Ok(Some(_))), "{:?}", part.outcome);
                assert!(whole.messages.starts_with(&part.messages));
            }
        }
        assert_eq!(complete, bags.len());
    }
}
