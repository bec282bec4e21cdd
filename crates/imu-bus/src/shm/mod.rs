//! The shared-memory contract between imud and its subscribers: iceoryx2 service names, the
//! daemon's non-blocking [`Publishers`], and the client side [`Subscription`] / [`Subscriber`].
//!
//! # Services
//!
//! An imud instance named `NAME` (the daemon's `--name`, `default` unless set) offers five
//! iceoryx2 `ipc` services (see [`ServiceNames::for_instance`]):
//!
//! | service name          | pattern           | payload (type name)                              |
//! |-----------------------|-------------------|--------------------------------------------------|
//! | `imud/NAME/raw`       | publish-subscribe | [`RawSample`] (`imud::RawSample.v1`)             |
//! | `imud/NAME/corrected` | publish-subscribe | [`CorrectedSample`] (`imud::CorrectedSample.v1`) |
//! | `imud/NAME/status`    | publish-subscribe | [`DaemonStatus`] (`imud::DaemonStatus.v3`)       |
//! | `imud/NAME/health`    | publish-subscribe | [`CalibrationHealth`] (`imud::CalibrationHealth.v1`) |
//! | `imud/NAME/event`     | event             | [`ShmEvent`] ids: 1 = samples, 2 = status, 3 = health |
//!
//! The publish-subscribe services use iceoryx2's *safe overflow*: when a subscriber's buffer is
//! full the oldest sample in it is overwritten, so a slow, stopped or dead subscriber never
//! stalls the daemon and a reader that falls behind sees the newest samples. A subscriber
//! notices what it missed from gaps in `seq` ([`Subscription::missed`]). Each service admits a
//! single publisher, so a second daemon with the same instance name fails to start instead of
//! interleaving samples.
//!
//! The daemon publishes a batch (a raw and a corrected sample) and then calls
//! [`Publishers::notify`] once; subscribers sleep on the event service's listener and drain
//! their buffer when woken, so no one polls.
//!
//! # Crash recovery
//!
//! iceoryx2 keeps its resources in shared memory and files under `/tmp/iceoryx2` (hence
//! `RemoveIPC=no` under systemd). A process killed with SIGKILL leaves a *dead node* behind;
//! [`Publishers::open`] removes the stale resources of every dead node it may access before it
//! opens the services, and [`Publishers::cleanup_dead_nodes`] does the same at run time (the
//! daemon calls it now and then so killed subscribers free their slots). A subscriber holds
//! the services open across a daemon crash and receives from the restarted daemon.

use std::error::Error as StdError;
use std::fmt;
use std::time::{Duration, Instant};

use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::Subscriber as IoxSubscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::event::EventOpenError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use serde::Deserialize;

use crate::sample::{CalibrationHealth, CorrectedSample, DaemonStatus, RawSample};

mod nodes;
mod owner;
mod publishers;
mod subscription;

use nodes::*;
pub use owner::{ProcessIdentity, UserId};
pub use publishers::*;
pub use subscription::*;

/// First component of every imud service name.
pub const SERVICE_PREFIX: &str = "imud";

/// Instance name used when none is given.
pub const DEFAULT_INSTANCE: &str = "default";

/// Longest accepted instance name, in bytes.
pub const MAX_INSTANCE_NAME_LEN: usize = 64;

/// How long to wait for another process that is already removing a dead node's resources.
const STALE_CLEANUP_TIMEOUT: Duration = Duration::from_secs(1);

/// How long a subscriber sleeps between attempts to open a service that does not exist yet.
const OPEN_RETRY_PERIOD: Duration = Duration::from_millis(50);

type IpcPubSub<T> = PubSubFactory<ipc::Service, T, ()>;

/// Errors of the shared-memory services. The message names the instance or service; the
/// iceoryx2 cause is the [`source`](std::error::Error::source).
#[derive(Debug, thiserror::Error)]
pub enum ShmError {
    /// The instance name cannot be part of a service name.
    #[error(
        "invalid imud instance name {instance:?}: use 1 to {MAX_INSTANCE_NAME_LEN} characters \
         from A-Z a-z 0-9 _ - ."
    )]
    InvalidInstanceName {
        /// The rejected name.
        instance: String,
    },
    /// The iceoryx2 node of this process could not be created.
    #[error("cannot create the iceoryx2 node {node:?} (is /tmp/iceoryx2 writable?)")]
    CreateNode {
        /// Name of the node.
        node: String,
        /// The iceoryx2 failure.
        #[source]
        source: iceoryx2::node::NodeCreationFailure,
    },
    /// Listing nodes to find dead ones failed.
    #[error("cannot list iceoryx2 nodes to remove the stale resources of dead processes")]
    ListNodes {
        /// The iceoryx2 failure.
        #[source]
        source: iceoryx2::node::NodeListFailure,
    },
    /// The daemon could not create (or open the existing) service.
    #[error(
        "cannot create or open the shared-memory service {service:?} (a subscriber may still hold \
         it from a run with other shm options)"
    )]
    CreateService {
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: BoxedCause,
    },
    /// Another process already publishes on the service.
    #[error(
        "another process ({}) is already publishing on {service:?} of the imud instance named \
         {instance:?}; stop it or choose another --name (if none runs, a dead one left resources \
         this user may not remove: run as its user or clean /tmp/iceoryx2)",
        .holder.map_or_else(|| "unknown".to_owned(), |h| h.to_string())
    )]
    AlreadyPublishing {
        /// The instance name.
        instance: String,
        /// The service name.
        service: String,
        /// The publishing process, when iceoryx2 lists it.
        holder: Option<ProcessIdentity>,
    },
    /// The service exists and another user created it: the daemon does not share it.
    #[error(
        "the shared-memory service {service:?} of the imud instance named {instance:?} was \
         created by {owner}, not by this process's user ({} belongs to them; {}); imud does \
         not share services another user prepared: stop that user's process or choose another \
         --name",
        .path.display(),
        owner::list_holders(.holders)
    )]
    ForeignService {
        /// The instance name.
        instance: String,
        /// The service name.
        service: String,
        /// The user who created it (owner of its static config under iceoryx2's root path).
        owner: UserId,
        /// The file (or the services directory, if this user may not look inside) they own.
        path: std::path::PathBuf,
        /// Processes of that user visible to this one (all of them when run as root).
        holders: Vec<ProcessIdentity>,
    },
    /// The service's creator or publisher is not a user the subscriber trusts.
    #[error(
        "the shared-memory service {service:?} is {what} {who}, which is not a trusted imud \
         publisher (trusted: {trusted}); refusing its samples (pass the daemon's user as the \
         trusted publisher if this is the imud you expect)"
    )]
    UntrustedPublisher {
        /// The service name.
        service: String,
        /// "created by" or "published by".
        what: &'static str,
        /// The creator's user or the publishing process.
        who: String,
        /// The trusted users, for the message.
        trusted: String,
    },
    /// The service did not appear within the open timeout.
    #[error(
        "no imud instance named {instance:?} is running (service {service:?} did not appear \
         within {:.1} s); start imud or pass its --name",
        .waited.as_secs_f64()
    )]
    NotRunning {
        /// The instance name.
        instance: String,
        /// The service that was looked for.
        service: String,
        /// How long the subscriber waited.
        waited: Duration,
    },
    /// The service exists but carries another payload type (a layout version mismatch).
    #[error(
        "the shared-memory service {service:?} does not carry {type_name:?}: imud and this \
         client disagree on the payload layout version; use matching builds"
    )]
    IncompatibleType {
        /// The service name.
        service: String,
        /// The type name this process expected.
        type_name: &'static str,
    },
    /// An existing service could not be opened.
    #[error("cannot open the shared-memory service {service:?}")]
    OpenService {
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: BoxedCause,
    },
    /// A port (publisher, subscriber, notifier, listener) could not be created.
    #[error("cannot create a {port} on the shared-memory service {service:?}")]
    CreatePort {
        /// The kind of port.
        port: &'static str,
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: BoxedCause,
    },
    /// A sample could not be published (it was counted in [`Publishers::drops`]).
    #[error("cannot publish a sample on {service:?}")]
    Publish {
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: BoxedCause,
    },
    /// Subscribers could not be notified.
    #[error("cannot notify the listeners of {service:?}")]
    Notify {
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: iceoryx2::port::notifier::NotifierNotifyError,
    },
    /// Receiving a sample failed.
    #[error("cannot receive from {service:?}")]
    Receive {
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: iceoryx2::port::ReceiveError,
    },
    /// Waiting on the event listener failed.
    #[error("cannot wait for events on {service:?}")]
    Wait {
        /// The service name.
        service: String,
        /// The iceoryx2 failure.
        #[source]
        source: ListenerWaitError,
    },
}

/// An iceoryx2 error carried as the source of a [`ShmError`].
pub type BoxedCause = Box<dyn StdError + Send + Sync + 'static>;

fn boxed<E: StdError + Send + Sync + 'static>(e: E) -> BoxedCause {
    Box::new(e)
}

/// The iceoryx2 service names of one imud instance.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    /// `imud/<instance>/raw`: [`RawSample`]s.
    pub raw: String,
    /// `imud/<instance>/corrected`: [`CorrectedSample`]s.
    pub corrected: String,
    /// `imud/<instance>/status`: [`DaemonStatus`] about once a second.
    pub status: String,
    /// `imud/<instance>/health`: [`CalibrationHealth`] after every still window.
    pub health: String,
    /// `imud/<instance>/event`: the event service that wakes subscribers ([`ShmEvent`]).
    pub event: String,
}

impl ServiceNames {
    /// The names for `instance`: `imud/<instance>/{raw,corrected,status,health,event}`.
    ///
    /// The name is not checked here; [`Publishers::open`] and [`Subscription::open`] reject
    /// names that [`validate_instance_name`] rejects.
    pub fn for_instance(instance: &str) -> ServiceNames {
        let base = format!("{SERVICE_PREFIX}/{instance}");
        ServiceNames {
            raw: format!("{base}/raw"),
            corrected: format!("{base}/corrected"),
            status: format!("{base}/status"),
            health: format!("{base}/health"),
            event: format!("{base}/event"),
        }
    }

    /// The publish-subscribe service of `stream`.
    pub fn of(&self, stream: Stream) -> &str {
        match stream {
            Stream::Raw => &self.raw,
            Stream::Corrected => &self.corrected,
            Stream::Status => &self.status,
            Stream::Health => &self.health,
        }
    }
}

/// Checks that `instance` is 1 to [`MAX_INSTANCE_NAME_LEN`] characters from `A-Z a-z 0-9 _ - .`.
pub fn validate_instance_name(instance: &str) -> Result<(), ShmError> {
    let ok = !instance.is_empty()
        && instance.len() <= MAX_INSTANCE_NAME_LEN
        && instance
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'));
    if ok {
        Ok(())
    } else {
        Err(ShmError::InvalidInstanceName {
            instance: instance.to_owned(),
        })
    }
}

/// One of the four publish-subscribe streams of an instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stream {
    /// [`RawSample`]s on `imud/<instance>/raw`.
    Raw,
    /// [`CorrectedSample`]s on `imud/<instance>/corrected`.
    Corrected,
    /// [`DaemonStatus`] on `imud/<instance>/status`.
    Status,
    /// [`CalibrationHealth`] on `imud/<instance>/health`.
    Health,
}

impl fmt::Display for Stream {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stream::Raw => "raw",
            Stream::Corrected => "corrected",
            Stream::Status => "status",
            Stream::Health => "health",
        })
    }
}

/// Sets iceoryx2's own log level to errors only (unless its environment variable says
/// otherwise): its start-up notices ("no config file was loaded") are noise on a daemon's log.
pub fn quiet_iceoryx2_logs() {
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
}

/// Applies [`quiet_iceoryx2_logs`] once per process, before the first node is created (so
/// every program using these services gets it without having to remember).
fn quiet_once() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(quiet_iceoryx2_logs);
}

/// Event ids sent on `imud/<instance>/event`. Every listener wakes on every id; the id tells
/// what changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(usize)]
pub enum ShmEvent {
    /// New raw and/or corrected samples were published.
    Samples = 1,
    /// A new [`DaemonStatus`] was published.
    Status = 2,
    /// A new [`CalibrationHealth`] was published.
    Health = 3,
}

impl ShmEvent {
    /// The iceoryx2 event id (1 = samples, 2 = status, 3 = health).
    pub const fn id(self) -> usize {
        self as usize
    }
}

/// A payload type that travels on one of the streams. Sealed: only the four types of
/// [`crate::sample`] implement it.
pub trait ShmPayload: ZeroCopySend + Copy + fmt::Debug + sealed::Sealed + 'static {
    /// The stream that carries this type.
    const STREAM: Stream;
    /// The iceoryx2 type name (also checked by iceoryx2 when a service is opened).
    const TYPE_NAME: &'static str;
    /// The daemon's sequence number, for types that have one (used to count missed samples).
    fn seq(&self) -> Option<u64>;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for crate::sample::RawSample {}
    impl Sealed for crate::sample::CorrectedSample {}
    impl Sealed for crate::sample::DaemonStatus {}
    impl Sealed for crate::sample::CalibrationHealth {}
}

impl ShmPayload for RawSample {
    const STREAM: Stream = Stream::Raw;
    const TYPE_NAME: &'static str = crate::sample::RAW_SAMPLE_TYPE_NAME;
    fn seq(&self) -> Option<u64> {
        Some(self.seq)
    }
}

impl ShmPayload for CorrectedSample {
    const STREAM: Stream = Stream::Corrected;
    const TYPE_NAME: &'static str = crate::sample::CORRECTED_SAMPLE_TYPE_NAME;
    fn seq(&self) -> Option<u64> {
        Some(self.seq)
    }
}

impl ShmPayload for DaemonStatus {
    const STREAM: Stream = Stream::Status;
    const TYPE_NAME: &'static str = crate::sample::DAEMON_STATUS_TYPE_NAME;
    fn seq(&self) -> Option<u64> {
        None
    }
}

impl ShmPayload for CalibrationHealth {
    const STREAM: Stream = Stream::Health;
    const TYPE_NAME: &'static str = crate::sample::CALIBRATION_HEALTH_TYPE_NAME;
    fn seq(&self) -> Option<u64> {
        None
    }
}

/// Sizes of the daemon's services (used when the daemon creates them). Deserializes from
/// kebab-case keys (`subscriber-buffer-size`, `history-size`, `max-subscribers`); missing keys
/// take the defaults (256, 1, 16).
///
/// A service that still exists (held open by a subscriber) keeps the sizes it was created with;
/// reopening it with larger sizes fails with [`ShmError::CreateService`].
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(default, deny_unknown_fields, rename_all = "kebab-case")]
pub struct ShmOptions {
    /// Samples a subscriber can hold before the oldest is overwritten (256 = 2.5 s at 100 Hz).
    pub subscriber_buffer_size: usize,
    /// Samples a newly connected subscriber receives from the past (1 = the latest).
    pub history_size: usize,
    /// Subscribers per stream; the event service admits four times as many listeners.
    pub max_subscribers: usize,
}

impl Default for ShmOptions {
    fn default() -> Self {
        ShmOptions {
            subscriber_buffer_size: 256,
            history_size: 1,
            max_subscribers: 16,
        }
    }
}

#[cfg(test)]
mod tests;
