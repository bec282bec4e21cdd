//! CDR decoding of every message type imud writes (`imu_rec::ros2`): no panic; a message that
//! decodes re-encodes to one that decodes to the same value; the same bytes cut before the
//! message's last byte never decode (a truncation is always named).

use std::fmt::Debug;

use imu_rec::ros2::{
    CalibrationHealthMsg, CalibrationMsg, CdrReader, DaemonStatusMsg, DiagnosticArray, Imu,
    MagneticField, RawFrameMsg, RawSampleMsg, RosMessage, Temperature,
};

use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "cdr",
    about: "CDR decoding of imud's ROS 2 message types (imu_rec::ros2::RosMessage)",
    check,
    seeds: Some(crate::seeds::cdr),
    dictionary: &[
        &[0x00, 0x01, 0x00, 0x00],
        &[0x00, 0x00, 0x00, 0x00],
        &[0x01, 0x00, 0x00, 0x00],
        &[0xFF, 0xFF, 0xFF, 0xFF],
        &[0x00, 0x00, 0xF8, 0x7F],
        &[0x00],
    ],
    ci_mutations: 500_000,
};

/// A message type's check.
type Check = fn(&[u8]);
/// A message type's default value, encoded.
type Encode = fn() -> Vec<u8>;

/// One message type's check, by the selector byte's value modulo the count.
const TYPES: &[(Check, Encode)] = &[
    (check_type::<Imu>, encoded::<Imu>),
    (check_type::<Temperature>, encoded::<Temperature>),
    (check_type::<MagneticField>, encoded::<MagneticField>),
    (check_type::<RawSampleMsg>, encoded::<RawSampleMsg>),
    (check_type::<RawFrameMsg>, encoded::<RawFrameMsg>),
    (check_type::<DaemonStatusMsg>, encoded::<DaemonStatusMsg>),
    (
        check_type::<CalibrationHealthMsg>,
        encoded::<CalibrationHealthMsg>,
    ),
    (check_type::<CalibrationMsg>, encoded::<CalibrationMsg>),
    (check_type::<DiagnosticArray>, encoded::<DiagnosticArray>),
];

/// Input: `[type selector, CDR message...]`.
fn check(data: &[u8]) {
    if let Some((&selector, message)) = data.split_first() {
        (TYPES[usize::from(selector) % TYPES.len()].0)(message);
    }
}

fn check_type<T: RosMessage + Debug>(data: &[u8]) {
    let Ok(mut r) = CdrReader::new(data) else {
        return;
    };
    let m = match T::read_fields(&mut r) {
        Ok(m) => m,
        Err(e) => {
            assert!(!e.to_string().is_empty(), "an error says what is wrong");
            return;
        }
    };
    let consumed = data.len() - r.remaining();
    let again = T::from_cdr(&m.to_cdr()).expect("a decoded message re-encodes decodably");
    assert_eq!(
        format!("{again:?}"),
        format!("{m:?}"),
        "a decoded message re-encodes to itself"
    );
    assert!(
        T::from_cdr(&data[..consumed - 1]).is_err(),
        "a message cut before its last byte does not decode"
    );
}

fn encoded<T: RosMessage + Default>() -> Vec<u8> {
    T::default().to_cdr()
}

/// One seed per type: its default value as its encoder writes it, after its selector; and `sensor_msgs` messages with
/// values.
pub(crate) fn samples() -> Vec<Vec<u8>> {
    let mut seeds: Vec<Vec<u8>> = TYPES
        .iter()
        .enumerate()
        .map(|(i, (_, encode))| {
            let mut input = vec![i as u8];
            input.extend(encode());
            input
        })
        .collect();
    for imu in crate::seeds::ros2_messages() {
        seeds.push([&[0u8][..], &imu].concat());
    }
    let temperature =
        imu_rec::recording::temperature_message(1_700_000_000_000_000_000, 25.5, "imu_link");
    seeds.push([&[1u8][..], &temperature.to_cdr()].concat());
    seeds
}
