//! The DDS side of a ROS 2 input (`input.ros2-topic`): a `rustdds` participant on the
//! configured domain, the topic under ROS 2's wire names (`rt/...`,
//! `sensor_msgs::msg::dds_::Imu_`), and per session a best-effort reader (which matches
//! reliable and best-effort writers alike) whose messages are read as a byte stream of frames
//! (`drivers::ros2_input::frame`), so the session runs the topic like a serial line.
//!
//! The messages are not decoded here: their CDR bytes go as they came (the encapsulation
//! header rebuilt from the sample's representation), and the driver decodes them with
//! imu-bus's CDR code, so a replayed recording decodes exactly what the live run did.

use std::pin::Pin;
use std::task::{Context, Poll};

use futures::Stream;
use rustdds::no_key::{DataReaderStream, DefaultDecoder, DeserializerAdapter};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{
    DomainParticipant, DomainParticipantBuilder, QosPolicies, QosPolicyBuilder,
    RepresentationIdentifier, Subscriber, Topic, TopicKind,
};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tracing::warn;

use super::Ros2Error;
use super::config::Ros2Config;
use crate::drivers::ros2_input::frame;

/// One sample's payload as received, with its CDR encapsulation header.
pub struct CdrMessage(Vec<u8>);

/// Takes a sample's bytes as they are (little- or big-endian plain CDR; the driver's decoder
/// says what it cannot read).
pub struct CdrMessageAdapter;

/// The representations a ROS 2 publisher writes `sensor_msgs/Imu` in.
const ENCODINGS: [RepresentationIdentifier; 2] = [
    RepresentationIdentifier::CDR_LE,
    RepresentationIdentifier::CDR_BE,
];

impl DeserializerAdapter<CdrMessage> for CdrMessageAdapter {
    type Error = std::convert::Infallible;
    type Decoded = CdrMessage;
    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &ENCODINGS
    }
    fn transform_decoded(decoded: CdrMessage) -> CdrMessage {
        decoded
    }
}

/// The decoder of [`CdrMessageAdapter`]: a copy with the encapsulation header in front.
#[derive(Clone, Copy)]
pub struct CdrMessageDecoder;

impl<'de> rustdds::no_key::Decode<'de, CdrMessage> for CdrMessageDecoder {
    type Error = std::convert::Infallible;
    fn decode_bytes(
        self,
        input_bytes: &'de [u8],
        encoding: RepresentationIdentifier,
    ) -> Result<CdrMessage, Self::Error> {
        // The representation identifier as it was on the wire (RTPS 10.2), options zero.
        let id = if encoding == RepresentationIdentifier::CDR_LE {
            [0x00, 0x01]
        } else {
            [0x00, 0x00]
        };
        let mut bytes = Vec::with_capacity(4 + input_bytes.len());
        bytes.extend_from_slice(&id);
        bytes.extend_from_slice(&[0, 0]);
        bytes.extend_from_slice(input_bytes);
        Ok(CdrMessage(bytes))
    }
}

impl DefaultDecoder<CdrMessage> for CdrMessageAdapter {
    type Decoder = CdrMessageDecoder;
    const DECODER: Self::Decoder = CdrMessageDecoder;
}

/// The participant and topic of a ROS 2 input, kept for the daemon's life; each session
/// opens a reader on them ([`Ros2InputLink::open`]).
pub struct Ros2InputLink {
    // Field order is drop order: subscriber and topic before their participant.
    subscriber: Subscriber,
    topic: Topic,
    qos: QosPolicies,
    dds_topic: String,
    _participant: DomainParticipant,
}

fn dds_error(what: String) -> impl FnOnce(rustdds::dds::CreateError) -> Ros2Error {
    move |e| Ros2Error::Dds {
        what,
        reason: e.to_string(),
    }
}

impl Ros2InputLink {
    /// The participant on `config`'s domain and the topic `topic` (a ROS 2 name, resolved in
    /// the namespace).
    pub fn new(config: &Ros2Config, topic: &str) -> Result<Self, Ros2Error> {
        let dds_topic = config.dds_topic(topic).ok_or_else(|| Ros2Error::Dds {
            what: "input topic".into(),
            reason: "the name is empty".into(),
        })?;
        let mut builder = DomainParticipantBuilder::new(config.domain_id);
        if !config.interfaces.is_empty() {
            builder = builder.with_only_networks(config.interfaces.iter().copied());
        }
        let participant = builder.build().map_err(dds_error(format!(
            "participant of the input on domain {}",
            config.domain_id
        )))?;
        // Best effort matches every writer (a reliable reader would not match a sensor-data
        // one); keep last so a late session never blocks the writer; volatile as ROS 2's
        // sensor-data profile.
        let qos = QosPolicyBuilder::new()
            .reliability(Reliability::BestEffort)
            .history(History::KeepLast {
                depth: i32::from(config.depth),
            })
            .durability(Durability::Volatile)
            .build();
        let subscriber = participant
            .create_subscriber(&qos)
            .map_err(dds_error("subscriber of the input".into()))?;
        let topic_handle = participant
            .create_topic(
                dds_topic.clone(),
                imu_bus::ros2::IMU_DEF.dds_type_name(),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(dds_error(format!("topic {dds_topic}")))?;
        Ok(Self {
            subscriber,
            topic: topic_handle,
            qos,
            dds_topic,
            _participant: participant,
        })
    }

    /// The topic's DDS name.
    pub fn dds_topic(&self) -> &str {
        &self.dds_topic
    }

    /// A new reader on the topic as the port of one session.
    pub fn open(&self) -> Result<Ros2Port, Ros2Error> {
        let reader = self
            .subscriber
            .create_datareader_no_key::<CdrMessage, CdrMessageAdapter>(
                &self.topic,
                Some(self.qos.clone()),
            )
            .map_err(dds_error(format!("reader of {}", self.dds_topic)))?;
        Ok(Ros2Port {
            stream: reader.async_sample_stream(),
            pending: Vec::with_capacity(512),
            at: 0,
            read_errors: 0,
        })
    }
}

/// A session's reader as a byte stream: each message one frame. Writes are accepted and
/// dropped (a subscriber sends nothing; the driver never asks to).
pub struct Ros2Port {
    stream: DataReaderStream<CdrMessage, CdrMessageAdapter>,
    /// The frame being read out, and how far.
    pending: Vec<u8>,
    at: usize,
    read_errors: u64,
}

impl AsyncRead for Ros2Port {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let this = self.get_mut();
        while this.at == this.pending.len() {
            match Pin::new(&mut this.stream).poll_next(cx) {
                Poll::Ready(Some(Ok(sample))) => {
                    this.pending.clear();
                    this.at = 0;
                    frame::encode(&sample.into_value().0, &mut this.pending);
                }
                Poll::Ready(Some(Err(e))) => {
                    // A sample rustdds could not hand over; the stream goes on.
                    this.read_errors += 1;
                    if this.read_errors == 1 {
                        warn!(
                            "DDS input: a sample could not be read ({e}); further ones are \
                             only counted"
                        );
                    }
                }
                // The reader ended: the line closed.
                Poll::Ready(None) => return Poll::Ready(Ok(())),
                Poll::Pending => return Poll::Pending,
            }
        }
        // One message per read, so each gets the time it was read at.
        let n = buf.remaining().min(this.pending.len() - this.at);
        buf.put_slice(&this.pending[this.at..this.at + n]);
        this.at += n;
        Poll::Ready(Ok(()))
    }
}

impl AsyncWrite for Ros2Port {
    fn poll_write(
        self: Pin<&mut Self>,
        _cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        Poll::Ready(Ok(buf.len()))
    }
    fn poll_flush(self: Pin<&mut Self>, _cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Poll::Ready(Ok(()))
    }
    fn poll_shutdown(self: Pin<&mut Self>, _cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Poll::Ready(Ok(()))
    }
}
