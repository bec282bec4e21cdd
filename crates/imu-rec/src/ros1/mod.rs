//! ROS 1: the serialization of its messages (`ser.rs`, the one decoder of that encoding) and
//! its bag files, format 2.0 (`bag.rs`, read front to back in bounded memory).
//!
//! ROS 1 serialization differs from ROS 2's CDR ([`crate::ros2`]): no encapsulation header,
//! no alignment (fields packed back to back, little-endian), strings are a `uint32` length and
//! the bytes without a NUL, `time` is two `uint32` (seconds, nanoseconds), and
//! `std_msgs/Header` starts with a `uint32 seq`. The messages decode into the same types the
//! ROS 2 side uses ([`crate::ros2::Imu`] ...), the sequence number dropped, so an analysis sees
//! one type whatever the recording's format.

pub mod bag;
mod ser;

pub use ser::*;
