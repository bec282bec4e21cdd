//! A live ROS 2 IMU as a device (`[input] ros2-topic`, `imud --ros2-input TOPIC`): the
//! `sensor_msgs/msg/Imu` messages of a topic, taken over DDS by `crate::ros2::input` and
//! handed to the session as a byte stream of frames (`frame.rs`), become readings
//! (`reading.rs`) like any unit's: calibration, health, shared memory, ROS 2 output and the
//! MCAP log follow unchanged.
//!
//! Time: the message's header stamp is the device clock (whole ns, so the fine loss tracker
//! learns the rate from the stamps and counts a loss for every missing interval), the time
//! the session read the message is the host time, and the clock fit maps one onto the other
//! as for a unit's own timer. Nothing is ever sent: start-up is the first usable message,
//! and a topic silent for `device.silence-timeout-s` fails the session (retried with
//! back-off).

/// The frames of the byte stream: their home is `imu_proto::ros2_frame`, with the other decoders
/// (the fuzz targets and replay share it).
pub use imu_proto::ros2_frame as frame;
pub mod reading;
#[cfg(test)]
mod tests;

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use imu_bus::recording::{FrameData, SampleFrame};
use imu_bus::sample::device_protocol;
use imu_proto::decoder::DecoderStats;
use tracing::info;

use super::{DeviceIdentity, Driver, DriverEvent, Held};
use crate::config::Config;
use crate::pipeline::{Acquisition, FrameSlot, Gains, SessionSpec};
use frame::{FrameDecoder, FrameEvent};

/// The input's name in the status, logs and metadata (`imud.device` `protocol`).
pub const NAME: &str = "ros2-input";

/// The pipeline's session of a ROS 2 input: streaming on the header stamps, no scale words.
pub fn session() -> SessionSpec {
    SessionSpec {
        gains: Gains::NOT_APPLICABLE,
        timebase: reading::TIMEBASE,
        acquisition: Acquisition::Streaming,
        // Nothing is asked of the publisher: imud takes what it sends.
        configuration_verified: false,
        status_protocol: device_protocol::ROS2_INPUT,
    }
}

/// A ROS 2 topic as a device (see the module docs).
pub struct Ros2InputDriver {
    /// The topic as configured, and its DDS name.
    topic: String,
    dds_topic: String,
    domain_id: u16,
    depth: u16,
    silence: Duration,
    decoder: FrameDecoder,
    readings: reading::Readings,
    /// The first usable message opens the session.
    streaming: bool,
    /// Waiting for the first usable message until this time.
    waiting: Option<Instant>,
    events: VecDeque<Held>,
}

impl Ros2InputDriver {
    /// The input `config` names (`input.ros2-topic`, resolved in `ros2.namespace`).
    pub fn new(config: &Config, topic: &str) -> Self {
        Self {
            topic: topic.to_string(),
            dds_topic: config.ros2.dds_topic(topic).unwrap_or_default(),
            domain_id: config.ros2.domain_id,
            depth: config.ros2.depth,
            silence: Duration::from_secs_f64(config.device.silence_timeout_s),
            decoder: FrameDecoder::default(),
            readings: reading::Readings::default(),
            streaming: false,
            waiting: None,
            events: VecDeque::new(),
        }
    }

    /// Messages that made no sample so far.
    pub fn unusable(&self) -> u64 {
        self.readings.unusable()
    }

    /// The first usable message: the session, the identity and readiness go out before it.
    fn open_session(&mut self) {
        self.streaming = true;
        self.waiting = None;
        info!(
            "ROS 2 input {} (DDS {}, domain {}): sensor_msgs/msg/Imu messages as samples, \
             header stamps as the device clock, rate learned from them",
            self.topic, self.dds_topic, self.domain_id
        );
        self.events
            .push_back(Held::Event(DriverEvent::Session(session())));
        self.events
            .push_back(Held::Event(DriverEvent::Identified(Box::new(
                self.identity(),
            ))));
        self.events.push_back(Held::Event(DriverEvent::Ready));
    }

    /// What the recording metadata (`imud.device`) says of the input.
    fn identity(&self) -> DeviceIdentity {
        DeviceIdentity {
            protocol: NAME,
            model: "sensor_msgs/msg/Imu over DDS".into(),
            firmware: "not applicable (a ROS 2 topic)".into(),
            serial: "not applicable (a ROS 2 topic)".into(),
            details: vec![
                ("topic".into(), self.topic.clone()),
                ("dds-topic".into(), self.dds_topic.clone()),
                ("dds-type".into(), imu_bus::ros2::IMU_DEF.dds_type_name()),
                ("domain-id".into(), self.domain_id.to_string()),
                (
                    "reader-qos".into(),
                    format!(
                        "best effort, keep last {}, volatile (matches reliable and \
                         best-effort writers)",
                        self.depth
                    ),
                ),
                (
                    "clock".into(),
                    "header.stamp (the publisher's clock, ns)".into(),
                ),
                (
                    "host-time".into(),
                    "when imud read the message from its DDS reader".into(),
                ),
                ("rate-hz".into(), "learned from the stamps".into()),
                ("magnetometer".into(), "false".into()),
                ("temperature".into(), "false".into()),
                ("configuration-verified".into(), "false".into()),
            ],
        }
    }
}

impl Driver for Ros2InputDriver {
    fn start(&mut self, now: Instant) {
        self.streaming = false;
        self.waiting = Some(now + self.silence);
    }

    fn handle_input(&mut self, bytes: &[u8], _now: Instant) {
        self.decoder.push(bytes);
    }

    fn poll_event(&mut self, slot: &mut FrameSlot) -> Option<DriverEvent> {
        if let Some(held) = self.events.pop_front() {
            return Some(held.hand_over(slot));
        }
        Some(match self.decoder.next_event()? {
            FrameEvent::Frame { offset, bytes } => {
                let content = self.readings.content(&bytes, &self.topic);
                if !self.streaming && content.reading.is_some() {
                    // The session's events go before its first frame.
                    self.open_session();
                    let frame = SampleFrame {
                        stream_offset: offset,
                        bytes: FrameData::from_vec(bytes),
                    };
                    self.events.push_back(Held::frame(frame, content));
                    return self.events.pop_front().map(|held| held.hand_over(slot));
                }
                slot.content = content;
                slot.set_frame(&bytes, offset);
                DriverEvent::Frame
            }
            FrameEvent::Rejected {
                offset,
                bytes,
                reason,
            } => DriverEvent::Rejected {
                bytes,
                offset,
                reason,
            },
        })
    }

    fn poll_transmit(&mut self, _out: &mut Vec<u8>) -> bool {
        // A subscriber sends nothing to the topic.
        false
    }

    fn poll_timeout(&self) -> Option<Instant> {
        self.waiting
    }

    fn handle_timeout(&mut self, now: Instant) {
        if self.waiting.is_some_and(|t| now >= t) {
            self.waiting = None;
            self.events
                .push_back(Held::Event(DriverEvent::Failed(anyhow::anyhow!(
                    "no usable sensor_msgs/msg/Imu message on {} (DDS topic {}, domain {}) within \
                 {:.1} s: is the publisher running on this domain (ROS_DOMAIN_ID)?",
                    self.topic,
                    self.dds_topic,
                    self.domain_id,
                    self.silence.as_secs_f64()
                ))));
        }
    }

    fn flush(&mut self) {
        self.decoder.flush();
        // The next usable message opens a new session (as after a reconnect).
        self.streaming = false;
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        None
    }

    fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    fn initial_session(&self) -> SessionSpec {
        session()
    }
}
