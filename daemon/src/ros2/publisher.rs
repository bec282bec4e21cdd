//! The DDS thread: one `rustdds` participant, a writer per topic, and the loop that turns queued
//! items into CDR messages (imu-bus's encoder) and writes them.

use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use imu_bus::recording::{
    ImuNoiseVariances, imu_message, magnetic_field_message, temperature_message,
};
use imu_bus::ros2::{self, MsgDefinition, RosMessage};
use imu_bus::{CorrectedSample, RawSample};
use rustdds::bytes::Bytes;
use rustdds::no_key::{DataWriter, SerializerAdapter};
use rustdds::policy::{Durability, History, Reliability};
use rustdds::{
    DataWriterStatus, DomainParticipant, DomainParticipantBuilder, QosPolicies, QosPolicyBuilder,
    RepresentationIdentifier, StatusEvented, TopicKind,
};

use super::config::{Ros2Config, Ros2Qos};
use super::handoff::{Next, Receiver};
use super::messages::{diagnostics, raw_imu_message};
use super::{Item, Ros2Error, Shared, stats_of};

/// One message already encoded as CDR fields (the bytes after the encapsulation header).
pub(super) struct CdrPayload(Bytes);

/// Hands [`CdrPayload`]s to rustdds as little-endian plain CDR.
pub(super) struct CdrPayloadAdapter;

impl SerializerAdapter<CdrPayload> for CdrPayloadAdapter {
    type Error = std::convert::Infallible;
    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }
    fn to_bytes(value: &CdrPayload) -> Result<Bytes, Self::Error> {
        Ok(value.0.clone())
    }
}

type Writer = DataWriter<CdrPayload, CdrPayloadAdapter>;

/// How long the thread sleeps with nothing queued before it looks at its writers' reader
/// matches again (so their status queues, four events deep, are read while no samples flow).
const IDLE_STATUS_POLL: Duration = Duration::from_millis(50);

/// How often a writer that has readers looks at its status queue while samples flow. Each look is
/// a syscall (rustdds drains its status channel's wake-up socket on every `try_recv`), and a
/// count that lags by this much can only send messages to nobody for that long; a writer without
/// readers looks before every write, so a reader that matches gets every message from then on.
const MATCHED_STATUS_POLL: Duration = Duration::from_millis(100);

/// Depth of a rustdds 0.15 writer's status queue (`sync_status_channel(4)` in
/// `create_datawriter`); when it is full, rustdds drops the newest event.
const STATUS_QUEUE_DEPTH: usize = 4;

/// A topic's writer and how many readers it is matched with.
struct TopicWriter {
    writer: Writer,
    /// Matched readers, from the writer's latest `PublicationMatched` status (it carries the
    /// current count, so only the newest event matters).
    readers: i32,
    /// The status queue was found full: newer events may have been dropped, so the count may be
    /// stale. Until an event is read from a queue that was not full, the topic is written
    /// whatever the count says (a message to nobody costs only CPU; a skipped one to a reader
    /// would be lost).
    count_uncertain: bool,
    /// When a writer with readers next looks at its status queue before a write.
    next_status_poll: Instant,
}

impl TopicWriter {
    fn new(writer: Writer) -> Self {
        Self {
            writer,
            readers: 0,
            count_uncertain: false,
            next_status_poll: Instant::now(),
        }
    }

    /// Reads the status queue if the reader count may have changed in a way that matters before
    /// a write: always while there are no readers, every [`MATCHED_STATUS_POLL`] otherwise.
    fn poll_status_before_write(&mut self) {
        let now = Instant::now();
        if self.has_readers() && now < self.next_status_poll {
            return;
        }
        self.poll_status();
        self.next_status_poll = now + MATCHED_STATUS_POLL;
    }

    /// Takes the writer's queued status events.
    fn poll_status(&mut self) {
        let mut events = 0;
        while let Some(status) = self.writer.try_recv_status() {
            events += 1;
            if let DataWriterStatus::PublicationMatched { current, .. } = status {
                self.readers = current.count();
            }
        }
        if events > 0 {
            self.count_uncertain = events >= STATUS_QUEUE_DEPTH;
        }
    }

    /// Whether a message on this topic can reach anybody.
    fn has_readers(&self) -> bool {
        self.readers > 0 || self.count_uncertain
    }
}

/// What the thread needs to start.
pub(super) struct Setup {
    pub config: Ros2Config,
    pub frame_id: String,
    pub instance: String,
}

/// The writers of the configured topics (`None`: the topic is off).
struct Writers {
    imu: Option<TopicWriter>,
    imu_raw: Option<TopicWriter>,
    mag: Option<TopicWriter>,
    temperature: Option<TopicWriter>,
    diagnostics: Option<TopicWriter>,
}

impl Writers {
    fn each(&mut self) -> impl Iterator<Item = &mut TopicWriter> {
        [
            &mut self.imu,
            &mut self.imu_raw,
            &mut self.mag,
            &mut self.temperature,
            &mut self.diagnostics,
        ]
        .into_iter()
        .flatten()
    }
}

/// The thread's state.
pub(super) struct Publisher {
    // Field order is drop order: writers before the participant they belong to.
    writers: Writers,
    _participant: DomainParticipant,
    setup: Setup,
    shared: Arc<Shared>,
    noise: Option<ImuNoiseVariances>,
    scratch: Vec<u8>,
    warned_write_failure: bool,
}

fn dds_error(what: impl Into<String>) -> impl FnOnce(rustdds::dds::CreateError) -> Ros2Error {
    let what = what.into();
    move |e| Ros2Error::Dds {
        what,
        reason: e.to_string(),
    }
}

/// The writers' QoS: the configured profile, or reliable for `/diagnostics` (a status a
/// second is what ROS 2's diagnostic tools expect reliably; best-effort readers match it too).
fn qos(profile: Ros2Qos, depth: u16) -> QosPolicies {
    let reliability = match profile {
        Ros2Qos::SensorData => Reliability::BestEffort,
        Ros2Qos::Reliable => Reliability::Reliable {
            max_blocking_time: rustdds::Duration::from_millis(10),
        },
    };
    QosPolicyBuilder::new()
        .reliability(reliability)
        .history(History::KeepLast {
            depth: i32::from(depth),
        })
        .durability(Durability::Volatile)
        .build()
}

impl Publisher {
    /// Creates the participant and the writers of every configured topic.
    pub(super) fn new(setup: Setup, shared: Arc<Shared>) -> Result<Self, Ros2Error> {
        let c = &setup.config;
        let mut builder = DomainParticipantBuilder::new(c.domain_id);
        if !c.interfaces.is_empty() {
            builder = builder.with_only_networks(c.interfaces.iter().copied());
        }
        let participant = builder
            .build()
            .map_err(dds_error(format!("participant on domain {}", c.domain_id)))?;
        let data_qos = qos(c.qos, c.depth);
        let diagnostics_qos = qos(Ros2Qos::Reliable, c.depth);
        let publisher = participant
            .create_publisher(&data_qos)
            .map_err(dds_error("publisher"))?;
        let writer = |name: &str, def: &MsgDefinition, q: &QosPolicies| {
            let Some(topic_name) = c.dds_topic(name) else {
                return Ok(None);
            };
            let topic = participant
                .create_topic(topic_name.clone(), def.dds_type_name(), q, TopicKind::NoKey)
                .map_err(dds_error(format!("topic {topic_name}")))?;
            publisher
                .create_datawriter_no_key::<CdrPayload, CdrPayloadAdapter>(&topic, Some(q.clone()))
                .map(|w| Some(TopicWriter::new(w)))
                .map_err(dds_error(format!("writer of {topic_name}")))
        };
        let t = &c.topics;
        let writers = Writers {
            imu: writer(&t.imu, &ros2::IMU_DEF, &data_qos)?,
            imu_raw: writer(&t.imu_raw, &ros2::IMU_DEF, &data_qos)?,
            mag: writer(&t.mag, &ros2::MAGNETIC_FIELD_DEF, &data_qos)?,
            temperature: writer(&t.temperature, &ros2::TEMPERATURE_DEF, &data_qos)?,
            diagnostics: writer(
                &t.diagnostics,
                &ros2::DIAGNOSTIC_ARRAY_DEF,
                &diagnostics_qos,
            )?,
        };
        tracing::info!(
            "ROS 2 output on DDS domain {}: {}",
            c.domain_id,
            [&t.imu, &t.imu_raw, &t.mag, &t.temperature, &t.diagnostics]
                .iter()
                .filter_map(|n| c.dds_topic(n))
                .collect::<Vec<_>>()
                .join(", ")
        );
        Ok(Self {
            writers,
            _participant: participant,
            setup,
            shared,
            noise: None,
            scratch: Vec::with_capacity(512),
            warned_write_failure: false,
        })
    }

    /// Publishes items until the sink is dropped and the queue is empty.
    pub(super) fn run(&mut self, mut rx: Receiver<Item>) {
        loop {
            match rx.next(IDLE_STATUS_POLL) {
                Next::Item(item) => self.handle(item),
                Next::Idle => self.writers.each().for_each(TopicWriter::poll_status),
                Next::Closed => return,
            }
        }
    }

    fn handle(&mut self, item: Item) {
        match item {
            Item::Sample { raw, corrected } => self.on_sample(&raw, &corrected),
            Item::Temperature { t_wall_ns, temp_c } => {
                self.write(Topic::Temperature, |setup, _, _| {
                    temperature_message(t_wall_ns, temp_c, &setup.frame_id)
                });
            }
            Item::Noise(noise) => self.noise = noise,
            Item::Status { t_wall_ns, status } => {
                self.write(Topic::Diagnostics, |setup, _, shared| {
                    let c = &setup.config;
                    diagnostics(
                        t_wall_ns,
                        &status,
                        stats_of(shared),
                        &c.node,
                        &setup.instance,
                    )
                });
            }
        }
    }

    /// A sample: `imu/data`, `imu/mag` and `imu/data_raw`.
    fn on_sample(&mut self, raw: &RawSample, c: &CorrectedSample) {
        self.write(Topic::Imu, |setup, noise, _| {
            imu_message(c, &setup.frame_id, noise)
        });
        self.write(Topic::Mag, |setup, noise, _| {
            magnetic_field_message(c, &setup.frame_id, noise)
        });
        self.write(Topic::ImuRaw, |setup, _, _| {
            raw_imu_message(raw, c, &setup.frame_id)
        });
    }

    /// Writes the message `make` builds to `topic`, if the topic is on and has a reader (the
    /// message is only built then).
    fn write<M: RosMessage>(
        &mut self,
        topic: Topic,
        make: impl FnOnce(&Setup, Option<&ImuNoiseVariances>, &Shared) -> M,
    ) {
        let writer = match topic {
            Topic::Imu => &mut self.writers.imu,
            Topic::ImuRaw => &mut self.writers.imu_raw,
            Topic::Mag => &mut self.writers.mag,
            Topic::Temperature => &mut self.writers.temperature,
            Topic::Diagnostics => &mut self.writers.diagnostics,
        };
        let Some(writer) = writer else { return };
        writer.poll_status_before_write();
        if !writer.has_readers() {
            // Volatile writers: a reader matched later would not get this message either.
            self.shared
                .not_sent_unmatched
                .fetch_add(1, Ordering::Relaxed);
            return;
        }
        let msg = make(&self.setup, self.noise.as_ref(), &self.shared);
        self.scratch.clear();
        msg.encode_into(&mut self.scratch);
        let payload = CdrPayload(Bytes::copy_from_slice(
            &self.scratch[ros2::CDR_LE_HEADER.len()..],
        ));
        match writer.writer.write(payload, None) {
            Ok(()) => {
                self.shared.written.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => {
                self.shared.write_failures.fetch_add(1, Ordering::Relaxed);
                if !self.warned_write_failure {
                    self.warned_write_failure = true;
                    tracing::warn!(
                        "DDS write failed ({e}); further failures are only counted \
                         (status publish_drops, /diagnostics dds_write_failures)"
                    );
                }
            }
        }
    }
}

/// The topics, for picking a writer.
#[derive(Debug, Clone, Copy)]
enum Topic {
    Imu,
    ImuRaw,
    Mag,
    Temperature,
    Diagnostics,
}
