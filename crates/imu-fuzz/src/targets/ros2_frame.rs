//! The ROS 2 input's `FrameDecoder` (`imu_proto::ros2_frame`): every byte reported exactly once,
//! in order; every frame event a whole frame whose length field is its message's length; the
//! `sensor_msgs/msg/Imu` decoding the input applies to each frame never panics.

use imu_proto::ros2_frame::{self, FrameDecoder, FrameEvent};
use imu_rec::ros2::{Imu, RosMessage};

use super::{assert_contiguous, check_stream, split_chunk_sizes, stream};
use crate::Target;

/// The target.
pub(crate) static TARGET: Target = Target {
    name: "ros2_frame",
    about: "frames of the ROS 2 input's byte stream (imu_proto::ros2_frame::FrameDecoder)",
    check,
    seeds: Some(crate::seeds::ros2_frame),
    dictionary: &[
        b"R2",
        b"R2\x04\x00\x00\x00",
        b"R2\xff\xff\x00\x00",
        b"R2\x00\x00\x01\x00",
        &[0x00, 0x01, 0x00, 0x00],
        &[0xFF, 0xFF, 0xFF, 0xFF],
        b"R",
    ],
    ci_mutations: 500_000,
};

/// Input: `[n_chunk_sizes, chunk sizes..., stream]`.
fn check(data: &[u8]) {
    if let Some((sizes, stream)) = split_chunk_sizes(data) {
        check_stream(FrameDecoder::default(), sizes, stream);
    }
}

stream!(FrameDecoder, FrameEvent, frame_bytes, account);

/// Checks one event and appends its bytes to `rebuilt`.
fn account(ev: FrameEvent, rebuilt: &mut Vec<u8>) {
    let (FrameEvent::Frame { offset, bytes } | FrameEvent::Rejected { offset, bytes, .. }) = &ev;
    assert_contiguous(*offset, bytes, rebuilt);
    if let FrameEvent::Frame { bytes, .. } = &ev {
        assert_eq!(
            bytes[..2],
            ros2_frame::MAGIC,
            "a frame starts with the magic"
        );
        let len = u32::from_le_bytes([bytes[2], bytes[3], bytes[4], bytes[5]]);
        let message = ros2_frame::message(bytes);
        assert_eq!(
            len as usize,
            message.len(),
            "the length field is the message's"
        );
        let _ = Imu::from_cdr(message);
    }
    rebuilt.extend_from_slice(bytes);
}
