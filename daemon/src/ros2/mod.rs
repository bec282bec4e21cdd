//! ROS 2 without a bridge: the daemon's samples as `sensor_msgs` topics on DDS (RTPS), which a
//! ROS 2 system on the same domain sees like any node's (`ros2 topic echo /imu/data`).
//!
//! The per-frame path hands each record it logs to [`Ros2Sink::offer`], which copies the few
//! plain values a topic needs into a bounded queue and returns: it never blocks and never
//! allocates; a full queue drops the message and counts it ([`Ros2Sink::drops`], added to the
//! status's `publish_drops`). The queue is a lock-free single-producer ring (`rtrb`); the thread
//! parks when it is empty and the producer unparks it only then (`handoff.rs`: one wake a
//! sample at most, and no lock either side can wait on). A thread (`imud-ros2`) owns the DDS
//! participant (`rustdds`, pure Rust) and its writers, encodes each message with imu-bus's CDR
//! encoder — the very messages the MCAP log stores, with the same stamps, frame id and
//! covariances — and writes it to the topics that have a matched reader.
//!
//! Wire names are ROS 2's: topic `rt/<namespace>/imu/data`, type
//! `sensor_msgs::msg::dds_::Imu_`, payload plain little-endian CDR. `config.rs`: the `[ros2]`
//! section; `publisher.rs`: the thread; `messages.rs`: the messages that are not the MCAP's;
//! `input.rs`: the other direction, a ROS 2 IMU topic subscribed to as the device
//! (`input.ros2-topic`), its own participant and one reader per session.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;

use imu_bus::recording::{ImuNoiseVariances, LogRecord};
use imu_bus::{CorrectedSample, DaemonStatus, RawSample};

pub mod config;
mod handoff;
pub mod input;
mod messages;
mod publisher;

pub use config::{Ros2Config, Ros2Qos, Ros2Topics};

/// Why the DDS output could not start.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// The participant, a topic or a writer could not be created (sockets, ports).
    #[error("DDS {what}: {reason}")]
    Dds {
        /// What was being created.
        what: String,
        /// The DDS library's reason.
        reason: String,
    },
    /// The thread could not be started.
    #[error("cannot start the DDS thread")]
    Spawn(#[source] std::io::Error),
    /// The thread ended before it reported its start-up (a bug).
    #[error("the DDS thread ended during start-up")]
    ThreadGone,
}

/// One message for the DDS thread: plain copies, no heap.
#[derive(Debug, Clone, Copy)]
enum Item {
    /// A sample with its raw record (`imu/data`, `imu/mag`, `imu/data_raw`).
    Sample {
        raw: RawSample,
        corrected: CorrectedSample,
    },
    Temperature {
        t_wall_ns: u64,
        temp_c: f64,
    },
    Noise(Option<ImuNoiseVariances>),
    Status {
        t_wall_ns: u64,
        status: DaemonStatus,
    },
}

/// Counters shared by the sink and its thread.
#[derive(Debug, Default)]
struct Shared {
    dropped_queue_full: AtomicU64,
    written: AtomicU64,
    write_failures: AtomicU64,
    not_sent_unmatched: AtomicU64,
}

/// Counters of the DDS output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Ros2Stats {
    /// DDS samples written (one per topic message).
    pub written: u64,
    /// Items dropped because the queue to the DDS thread was full.
    pub dropped_queue_full: u64,
    /// Messages the DDS writer refused (a reliable send window full past its blocking time).
    pub write_failures: u64,
    /// Messages not written because no reader of their topic was matched (nobody to send to:
    /// the writers are volatile, so a reader matched later would not have received them either).
    pub not_sent_unmatched: u64,
}

/// The daemon's DDS output: a bounded queue to the thread that publishes.
///
/// Dropping it lets the thread write what is queued, then ends the participant.
pub struct Ros2Sink {
    tx: Option<handoff::Sender<Item>>,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Ros2Sink {
    /// Creates the participant, the topics and their writers (on the DDS thread, whose start-up
    /// result this waits for). `instance` is the daemon's name (in the diagnostics).
    pub fn start(config: &Ros2Config, frame_id: &str, instance: &str) -> Result<Self, Ros2Error> {
        let (tx, rx) = handoff::channel(config.queue_capacity);
        let shared = Arc::new(Shared::default());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let setup = publisher::Setup {
            config: config.clone(),
            frame_id: config.frame_id.clone().unwrap_or_else(|| frame_id.into()),
            instance: instance.into(),
        };
        let thread_shared = shared.clone();
        let thread = std::thread::Builder::new()
            .name("imud-ros2".into())
            .spawn(
                move || match publisher::Publisher::new(setup, thread_shared) {
                    Ok(mut p) => {
                        let _ = ready_tx.send(Ok(()));
                        p.run(rx);
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                    }
                },
            )
            .map_err(Ros2Error::Spawn)?;
        ready_rx.recv().map_err(|_| Ros2Error::ThreadGone)??;
        let tx = tx.bind(thread.thread().clone());
        Ok(Self {
            tx: Some(tx),
            shared,
            thread: Some(thread),
        })
    }

    /// Queues what a topic needs from one logged record; never blocks.
    pub fn offer(&self, record: &LogRecord) {
        let item = match record {
            LogRecord::Sample { raw, corrected, .. } => Item::Sample {
                raw: *raw,
                corrected: *corrected,
            },
            LogRecord::Temperature { t_wall_ns, temp_c } => Item::Temperature {
                t_wall_ns: *t_wall_ns,
                temp_c: *temp_c,
            },
            LogRecord::Calibration { noise, .. } => Item::Noise(*noise),
            LogRecord::Status { t_wall_ns, status } => Item::Status {
                t_wall_ns: *t_wall_ns,
                status: *status,
            },
            // The health states reach /diagnostics with the status (`health_accel`,
            // `health_gyro`); the per-window reports are on shared memory and in the MCAP.
            // The pipeline logs every sample as one `Sample`; separate raw and corrected records
            // are other producers' (the recorder's tests), never the daemon's.
            LogRecord::RawFrame { .. }
            | LogRecord::Health(_)
            | LogRecord::Raw(_)
            | LogRecord::Corrected(_) => return,
        };
        self.send(item);
    }

    /// Queues a status for `/diagnostics`.
    pub fn status(&self, t_wall_ns: u64, status: &DaemonStatus) {
        self.send(Item::Status {
            t_wall_ns,
            status: *status,
        });
    }

    fn send(&self, item: Item) {
        let Some(tx) = &self.tx else { return };
        if !tx.try_send(item) {
            self.shared
                .dropped_queue_full
                .fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Messages lost so far: dropped at the queue or refused by the writer.
    pub fn drops(&self) -> u64 {
        let s = self.stats();
        s.dropped_queue_full + s.write_failures
    }

    /// The counters now.
    pub fn stats(&self) -> Ros2Stats {
        stats_of(&self.shared)
    }

    /// Writes what is queued, ends the participant (its readers see it leave) and returns the
    /// final counters.
    pub fn finish(mut self) -> Ros2Stats {
        self.shutdown();
        self.stats()
    }

    fn shutdown(&mut self) {
        if let Some(tx) = self.tx.take() {
            tx.close();
        }
        if let Some(t) = self.thread.take()
            && t.join().is_err()
        {
            tracing::error!("the DDS thread panicked");
        }
    }
}

fn stats_of(shared: &Shared) -> Ros2Stats {
    Ros2Stats {
        written: shared.written.load(Ordering::Relaxed),
        dropped_queue_full: shared.dropped_queue_full.load(Ordering::Relaxed),
        write_failures: shared.write_failures.load(Ordering::Relaxed),
        not_sent_unmatched: shared.not_sent_unmatched.load(Ordering::Relaxed),
    }
}

impl Drop for Ros2Sink {
    fn drop(&mut self) {
        self.shutdown();
    }
}
