//! ROS 1 deserialization (`imu_rec::ros1::Ros1Message`: `sensor_msgs/Imu`, `Temperature`): no
//! panic; a message that decodes decodes the same from exactly the bytes it read, and those
//! bytes cut before their last byte never decode (a truncation is always named).

use std::fmt::Debug;

use imu_rec::ros1::{Ros1Message, Ros1Reader};
use imu_rec::ros2::{Imu, Temperature};

use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "ros1_message",
    about: "ROS 1 deserialization of sensor_msgs/Imu and Temperature (imu_rec::ros1)",
    check,
    seeds: Some(seeds),
    dictionary: &[
        &[0x00, 0x00, 0x00, 0x00],
        &[0x01, 0x00, 0x00, 0x00],
        &[0xFF, 0xFF, 0xFF, 0xFF],
        &[0x00, 0x00, 0xF8, 0x7F],
        b"imu_link",
    ],
    ci_mutations: 500_000,
};

/// A message type's check.
type Check = fn(&[u8]);

/// One message type's check, by the selector byte's value modulo the count.
const TYPES: &[(&str, Check)] = &[
    (Imu::TYPE, check_type::<Imu>),
    (Temperature::TYPE, check_type::<Temperature>),
];

/// Input: `[type selector, ROS 1 message...]`.
fn check(data: &[u8]) {
    if let Some((&selector, message)) = data.split_first() {
        (TYPES[usize::from(selector) % TYPES.len()].1)(message);
    }
}

fn check_type<T: Ros1Message + Debug>(data: &[u8]) {
    let mut r = Ros1Reader::new(data);
    let m = match T::read_ros1(&mut r) {
        Ok(m) => m,
        Err(e) => {
            assert!(!e.to_string().is_empty(), "an error says what is wrong");
            return;
        }
    };
    let consumed = data.len() - r.remaining();
    let again = T::from_ros1(&data[..consumed]).expect("the bytes read decode alone");
    assert_eq!(
        format!("{again:?}"),
        format!("{m:?}"),
        "trailing bytes do not change a message"
    );
    assert!(
        consumed > 0 && T::from_ros1(&data[..consumed - 1]).is_err(),
        "a message cut before its last byte does not decode"
    );
}

/// The messages of the committed ROS 1 bag corpus (written by Python `rosbags`), each after
/// the selector of its type.
fn seeds() -> Vec<Vec<u8>> {
    let Ok(bags) = crate::corpus::load(&super::ros1_bag::TARGET.corpus_dir()) else {
        return Vec::new();
    };
    let mut seeds = Vec::new();
    for bag in bags {
        let Some((_, file)) = super::files::split_cut(&bag) else {
            continue;
        };
        for m in super::ros1_bag::read(file).messages {
            if let Some(i) = TYPES.iter().position(|(t, _)| *t == m.msg_type) {
                seeds.push([&[i as u8][..], &m.data].concat());
            }
        }
    }
    seeds.sort();
    seeds.dedup();
    seeds
}
