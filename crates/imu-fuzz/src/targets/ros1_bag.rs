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

    #[test]
    fn a_bag_cut_in_any_record_s_length_fields_keeps_a_prefix() {
        // Each cut lands in a top-level record's header-length or data-length field (where a
        // reader once handed the previous chunk over again, found by libFuzzer), or every 61st
        // byte; every cut reads as a prefix of the whole bag, and one past the bag header record
        // is reported unfinished.
        let bags = crate::corpus::load(&TARGET.corpus_dir()).unwrap();
        for bag in &bags {
            let (_, file) = split_cut(bag).unwrap();
            let whole = read(file);
            let le = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().unwrap()) as usize;
            let mut cuts: Vec<usize> = (0..file.len()).step_by(61).collect();
            let mut at = imu_rec::ros1::bag::ROSBAG_V2.len();
            let mut bag_header_end = None;
            while at + 4 <= file.len() {
                let data_len_at = at + 4 + le(at);
                cuts.extend((at + 1..at + 4).chain(data_len_at + 1..data_len_at + 4));
                at = data_len_at + 4 + le(data_len_at);
                bag_header_end.get_or_insert(at);
            }
            assert_eq!(at, file.len(), "the walk ends at the file's end");
            for cut in cuts {
                let part = read(&file[..cut]);
                assert!(
                    whole.messages.starts_with(&part.messages),
                    "cut at {cut} of {}: {} messages, not the first of the whole's {}",
                    file.len(),
                    part.messages.len(),
                    whole.messages.len()
                );
                // Cut before its bag header record ends, a file is no bag (an error, no messages).
                if bag_header_end.is_some_and(|end| cut >= end) {
                    assert!(
                        matches!(part.outcome, Ok(Some(_))),
                        "cut at {cut}: {:?}",
                        part.outcome
                    );
                }
            }
        }
    }
}
