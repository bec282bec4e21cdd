//! The shared-memory contract between imud and its subscribers: iceoryx2 service names, the
//! daemon's non-blocking [`Publishers`], and the client side [`Subscription`] / [`Subscriber`].
//!
//! # Services
//!
//! An imud instance named `NAME` (the daemon's `--name`, `default` unless set) offers four
//! iceoryx2 `ipc` services (see [`ServiceNames::for_instance`]):
//!
//! | service name          | pattern           | payload (type name)                              |
//! |-----------------------|-------------------|--------------------------------------------------|
//! | `imud/NAME/raw`       | publish-subscribe | [`RawSample`] (`imud::RawSample.v1`)             |
//! | `imud/NAME/corrected` | publish-subscribe | [`CorrectedSample`] (`imud::CorrectedSample.v1`) |
//! | `imud/NAME/status`    | publish-subscribe | [`DaemonStatus`] (`imud::DaemonStatus.v2`)       |
//! | `imud/NAME/event`     | event             | [`ShmEvent`] ids: 1 = samples, 2 = status        |
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

use crate::sample::{CorrectedSample, DaemonStatus, RawSample};

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
        "another imud instance named {instance:?} is already publishing on {service:?}; stop it \
         or choose another --name (if none runs, a dead one left resources this user may not \
         remove: run as its user or clean /tmp/iceoryx2)"
    )]
    AlreadyPublishing {
        /// The instance name.
        instance: String,
        /// The service name.
        service: String,
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
    /// `imud/<instance>/event`: the event service that wakes subscribers ([`ShmEvent`]).
    pub event: String,
}

impl ServiceNames {
    /// The names for `instance`: `imud/<instance>/{raw,corrected,status,event}`.
    ///
    /// The name is not checked here; [`Publishers::open`] and [`Subscription::open`] reject
    /// names that [`validate_instance_name`] rejects.
    pub fn for_instance(instance: &str) -> ServiceNames {
        let base = format!("{SERVICE_PREFIX}/{instance}");
        ServiceNames {
            raw: format!("{base}/raw"),
            corrected: format!("{base}/corrected"),
            status: format!("{base}/status"),
            event: format!("{base}/event"),
        }
    }

    /// The publish-subscribe service of `stream`.
    pub fn of(&self, stream: Stream) -> &str {
        match stream {
            Stream::Raw => &self.raw,
            Stream::Corrected => &self.corrected,
            Stream::Status => &self.status,
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

/// One of the three sample streams of an instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Stream {
    /// [`RawSample`]s on `imud/<instance>/raw`.
    Raw,
    /// [`CorrectedSample`]s on `imud/<instance>/corrected`.
    Corrected,
    /// [`DaemonStatus`] on `imud/<instance>/status`.
    Status,
}

impl fmt::Display for Stream {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stream::Raw => "raw",
            Stream::Corrected => "corrected",
            Stream::Status => "status",
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
}

impl ShmEvent {
    /// The iceoryx2 event id (1 = samples, 2 = status).
    pub const fn id(self) -> usize {
        self as usize
    }
}

/// A payload type that travels on one of the streams. Sealed: only the three types of
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
    /// Subscribers per stream; the event service admits three times as many listeners.
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

/// Removes the stale resources of every dead iceoryx2 node this process may access and
/// returns how many are gone (removed here or concurrently by another process). Nodes of other
/// users that we may not touch are skipped.
fn remove_dead_nodes(config: &Config) -> Result<u64, ShmError> {
    let mut dead = Vec::new();
    Node::<ipc::Service>::list(config, |state| {
        if let NodeState::Dead(view) = state {
            dead.push(view);
        }
        CallbackProgression::Continue
    })
    .map_err(|source| ShmError::ListNodes { source })?;
    let mut removed = 0;
    for view in dead {
        // If another process is cleaning the same node, wait for it: the dead publisher must be
        // gone before ours is created. Failures (e.g. another user's node) are skipped.
        if view
            .blocking_remove_stale_resources(STALE_CLEANUP_TIMEOUT)
            .is_ok()
        {
            removed += 1;
        }
    }
    Ok(removed)
}

fn node_name(role: &str, instance: &str) -> String {
    format!("{role}-{instance}")
}

fn create_node(name: &str) -> Result<Node<ipc::Service>, ShmError> {
    let node_name = NodeName::new(name).map_err(|_| ShmError::InvalidInstanceName {
        instance: name.to_owned(),
    })?;
    NodeBuilder::new()
        .name(&node_name)
        // The library never installs signal handlers: the daemon and clients own theirs.
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|source| ShmError::CreateNode {
            node: name.to_owned(),
            source,
        })
}

fn service_name(name: &str, instance: &str) -> Result<ServiceName, ShmError> {
    ServiceName::new(name).map_err(|_| ShmError::InvalidInstanceName {
        instance: instance.to_owned(),
    })
}

/// One publish-subscribe service with its single publisher.
struct Channel<T: ShmPayload> {
    name: String,
    service: IpcPubSub<T>,
    publisher: Publisher<ipc::Service, T, ()>,
}

impl<T: ShmPayload> Channel<T> {
    fn open(
        node: &Node<ipc::Service>,
        instance: &str,
        name: &str,
        options: &ShmOptions,
    ) -> Result<Self, ShmError> {
        let service = node
            .service_builder(&service_name(name, instance)?)
            .publish_subscribe::<T>()
            .enable_safe_overflow(true)
            .subscriber_max_buffer_size(options.subscriber_buffer_size)
            .history_size(options.history_size)
            .max_subscribers(options.max_subscribers)
            .max_publishers(1)
            .max_nodes(options.max_subscribers + 1)
            .open_or_create()
            .map_err(|e| ShmError::CreateService {
                service: name.to_owned(),
                source: boxed(e),
            })?;
        let publisher = service.publisher_builder().create().map_err(|e| match e {
            PublisherCreateError::ExceedsMaxSupportedPublishers => ShmError::AlreadyPublishing {
                instance: instance.to_owned(),
                service: name.to_owned(),
            },
            e => ShmError::CreatePort {
                port: "publisher",
                service: name.to_owned(),
                source: boxed(e),
            },
        })?;
        Ok(Channel {
            name: name.to_owned(),
            service,
            publisher,
        })
    }

    /// Loans a slot, writes the sample into it and sends it: no allocation, never blocks.
    fn publish(&self, sample: &T, drops: &mut u64) -> Result<usize, ShmError> {
        let sent = match self.publisher.loan_uninit() {
            Ok(slot) => slot.write_payload(*sample).send().map_err(boxed),
            Err(e) => Err(boxed(e)),
        };
        sent.map_err(|source| {
            *drops += 1;
            ShmError::Publish {
                service: self.name.clone(),
                source,
            }
        })
    }
}

/// The daemon's side of the services: one publisher per stream and a notifier.
///
/// Every `publish_*` call loans a shared-memory slot, writes the sample into it and sends it
/// without allocating and without ever waiting for a subscriber. Not `Send`: the daemon
/// publishes from one thread.
pub struct Publishers {
    instance: String,
    names: ServiceNames,
    node: Node<ipc::Service>,
    raw: Channel<RawSample>,
    corrected: Channel<CorrectedSample>,
    status: Channel<DaemonStatus>,
    _event: EventFactory<ipc::Service>,
    notifier: Notifier<ipc::Service>,
    drops: u64,
    stale_nodes_removed: u64,
}

impl fmt::Debug for Publishers {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Publishers")
            .field("instance", &self.instance)
            .field("drops", &self.drops)
            .field("stale_nodes_removed", &self.stale_nodes_removed)
            .finish_non_exhaustive()
    }
}

impl Publishers {
    /// Removes the stale resources of dead nodes (a previous run killed with SIGKILL), then
    /// creates the node `imud-<instance>`, opens or creates the four services of `instance` and
    /// a publisher on each.
    ///
    /// Fails with [`ShmError::AlreadyPublishing`] when a live process publishes on the same
    /// instance.
    pub fn open(instance: &str, options: &ShmOptions) -> Result<Publishers, ShmError> {
        quiet_once();
        validate_instance_name(instance)?;
        let names = ServiceNames::for_instance(instance);
        let stale_nodes_removed = remove_dead_nodes(Config::global_config())?;
        let node = create_node(&node_name("imud", instance))?;

        // The event service first: a subscriber that sees a sample service can open it too.
        let event = node
            .service_builder(&service_name(&names.event, instance)?)
            .event()
            // Every subscription (of any of the three streams) brings a node and a listener.
            .max_listeners(options.max_subscribers * 3)
            .max_nodes(options.max_subscribers * 3 + 1)
            .open_or_create()
            .map_err(|e| ShmError::CreateService {
                service: names.event.clone(),
                source: boxed(e),
            })?;
        let notifier = event
            .notifier_builder()
            .create()
            .map_err(|e| ShmError::CreatePort {
                port: "notifier",
                service: names.event.clone(),
                source: boxed(e),
            })?;
        let raw = Channel::open(&node, instance, &names.raw, options)?;
        let corrected = Channel::open(&node, instance, &names.corrected, options)?;
        let status = Channel::open(&node, instance, &names.status, options)?;
        Ok(Publishers {
            instance: instance.to_owned(),
            names,
            node,
            raw,
            corrected,
            status,
            _event: event,
            notifier,
            drops: 0,
            stale_nodes_removed,
        })
    }

    /// The instance name.
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// The service names of this instance.
    pub fn names(&self) -> &ServiceNames {
        &self.names
    }

    /// Publishes a raw sample; returns how many subscribers it reached. Never blocks; on
    /// failure the sample is counted in [`drops`](Self::drops).
    pub fn publish_raw(&mut self, sample: &RawSample) -> Result<usize, ShmError> {
        self.raw.publish(sample, &mut self.drops)
    }

    /// Publishes a corrected sample; returns how many subscribers it reached. Never blocks; on
    /// failure the sample is counted in [`drops`](Self::drops).
    pub fn publish_corrected(&mut self, sample: &CorrectedSample) -> Result<usize, ShmError> {
        self.corrected.publish(sample, &mut self.drops)
    }

    /// Publishes a status; returns how many subscribers it reached. Never blocks; on failure it
    /// is counted in [`drops`](Self::drops).
    pub fn publish_status(&mut self, status: &DaemonStatus) -> Result<usize, ShmError> {
        self.status.publish(status, &mut self.drops)
    }

    /// Wakes every subscriber waiting on this instance (call once per published batch);
    /// returns how many listeners were notified. Never blocks.
    pub fn notify(&mut self, event: ShmEvent) -> Result<usize, ShmError> {
        self.notifier
            .notify_with_custom_event_id(EventId::new(event.id()))
            .map_err(|source| ShmError::Notify {
                service: self.names.event.clone(),
                source,
            })
    }

    /// Samples that could not be published since [`open`](Self::open) (a failed loan or send).
    /// Samples a slow subscriber lost to overwriting are not visible here; the subscriber
    /// counts them from `seq` gaps ([`Subscription::missed`]).
    pub fn drops(&self) -> u64 {
        self.drops
    }

    /// Subscribers currently connected to `stream`.
    pub fn subscribers(&self, stream: Stream) -> usize {
        match stream {
            Stream::Raw => self.raw.service.dynamic_config().number_of_subscribers(),
            Stream::Corrected => self
                .corrected
                .service
                .dynamic_config()
                .number_of_subscribers(),
            Stream::Status => self.status.service.dynamic_config().number_of_subscribers(),
        }
    }

    /// Dead nodes whose stale resources were gone after [`open`](Self::open) cleaned up.
    pub fn stale_nodes_removed(&self) -> u64 {
        self.stale_nodes_removed
    }

    /// Removes the resources of nodes that died since (e.g. subscribers killed with SIGKILL,
    /// which otherwise keep their subscriber slot); returns how many were removed.
    pub fn cleanup_dead_nodes(&self) -> u64 {
        self.node.try_cleanup_dead_nodes().cleanups
    }
}

/// A subscriber to one stream of an imud instance, woken by the instance's event service.
pub struct Subscription<T: ShmPayload> {
    instance: String,
    service_name: String,
    _node: Node<ipc::Service>,
    service: IpcPubSub<T>,
    subscriber: IoxSubscriber<ipc::Service, T, ()>,
    _event: EventFactory<ipc::Service>,
    listener: Listener<ipc::Service>,
    last_seq: Option<u64>,
    received: u64,
    missed: u64,
}

impl<T: ShmPayload> fmt::Debug for Subscription<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Subscription")
            .field("service", &self.service_name)
            .field("received", &self.received)
            .field("missed", &self.missed)
            .finish_non_exhaustive()
    }
}

/// Retries `open` while the service does not exist (yet), up to `deadline`.
fn open_with_retry<F, R, E>(
    instance: &str,
    service: &str,
    started: Instant,
    deadline: Instant,
    mut open: F,
    is_missing: impl Fn(&E) -> bool,
) -> Result<R, Result<E, ShmError>>
where
    F: FnMut() -> Result<R, E>,
{
    loop {
        match open() {
            Ok(r) => return Ok(r),
            Err(e) if is_missing(&e) => {
                let now = Instant::now();
                if now >= deadline {
                    return Err(Err(ShmError::NotRunning {
                        instance: instance.to_owned(),
                        service: service.to_owned(),
                        waited: now - started,
                    }));
                }
                std::thread::sleep(OPEN_RETRY_PERIOD.min(deadline - now));
            }
            Err(e) => return Err(Ok(e)),
        }
    }
}

impl<T: ShmPayload> Subscription<T> {
    /// Opens `imud/<instance>/<stream of T>` and the event service, waiting up to
    /// `open_timeout` for a daemon to create them (so a client may start before the daemon).
    ///
    /// Fails with [`ShmError::NotRunning`] when the services do not appear in time and with
    /// [`ShmError::IncompatibleType`] when the daemon publishes another layout version.
    pub fn open(instance: &str, open_timeout: Duration) -> Result<Self, ShmError> {
        quiet_once();
        validate_instance_name(instance)?;
        let names = ServiceNames::for_instance(instance);
        let name = names.of(T::STREAM).to_owned();
        let node = create_node(&node_name(&format!("imu-sub-{}", T::STREAM), instance))?;
        let started = Instant::now();
        let deadline = started + open_timeout;

        let pubsub_name = service_name(&name, instance)?;
        let service = open_with_retry(
            instance,
            &name,
            started,
            deadline,
            || {
                node.service_builder(&pubsub_name)
                    .publish_subscribe::<T>()
                    .open()
            },
            |e| {
                matches!(
                    e,
                    PublishSubscribeOpenError::DoesNotExist
                        | PublishSubscribeOpenError::IsMarkedForDestruction
                        | PublishSubscribeOpenError::HangsInCreation
                )
            },
        )
        .map_err(|e| match e {
            Err(shm) => shm,
            Ok(PublishSubscribeOpenError::IncompatibleTypes) => ShmError::IncompatibleType {
                service: name.clone(),
                type_name: T::TYPE_NAME,
            },
            Ok(e) => ShmError::OpenService {
                service: name.clone(),
                source: boxed(e),
            },
        })?;

        let event_name = service_name(&names.event, instance)?;
        let event = open_with_retry(
            instance,
            &names.event,
            started,
            deadline,
            || node.service_builder(&event_name).event().open(),
            |e| {
                matches!(
                    e,
                    EventOpenError::DoesNotExist
                        | EventOpenError::IsMarkedForDestruction
                        | EventOpenError::HangsInCreation
                )
            },
        )
        .map_err(|e| match e {
            Err(shm) => shm,
            Ok(e) => ShmError::OpenService {
                service: names.event.clone(),
                source: boxed(e),
            },
        })?;

        let subscriber =
            service
                .subscriber_builder()
                .create()
                .map_err(|e| ShmError::CreatePort {
                    port: "subscriber",
                    service: name.clone(),
                    source: boxed(e),
                })?;
        let listener = event
            .listener_builder()
            .create()
            .map_err(|e| ShmError::CreatePort {
                port: "listener",
                service: names.event.clone(),
                source: boxed(e),
            })?;
        Ok(Subscription {
            instance: instance.to_owned(),
            service_name: name,
            _node: node,
            service,
            subscriber,
            _event: event,
            listener,
            last_seq: None,
            received: 0,
            missed: 0,
        })
    }

    /// The instance name.
    pub fn instance(&self) -> &str {
        &self.instance
    }

    /// The publish-subscribe service this subscription reads.
    pub fn service_name(&self) -> &str {
        &self.service_name
    }

    /// Takes one sample if one is buffered; never blocks.
    pub fn try_recv(&mut self) -> Result<Option<T>, ShmError> {
        let sample = self
            .subscriber
            .receive()
            .map_err(|source| ShmError::Receive {
                service: self.service_name.clone(),
                source,
            })?;
        Ok(sample.map(|s| {
            let value = *s.payload();
            self.account(&value);
            value
        }))
    }

    /// Appends every buffered sample to `out` without blocking; returns how many.
    pub fn drain_into(&mut self, out: &mut Vec<T>) -> Result<usize, ShmError> {
        let before = out.len();
        while let Some(sample) = self.try_recv()? {
            out.push(sample);
        }
        Ok(out.len() - before)
    }

    /// Returns the buffered samples; if there are none, sleeps on the event listener until the
    /// daemon announces new data or `timeout` has passed (then the result may be empty). A
    /// signal delivered to the process also ends the wait early, so a caller that sets a flag
    /// in its SIGINT handler sees it promptly.
    pub fn wait(&mut self, timeout: Duration) -> Result<Vec<T>, ShmError> {
        let mut out = Vec::new();
        self.wait_into(timeout, &mut out)?;
        Ok(out)
    }

    /// [`wait`](Self::wait) that appends to `out` (reuse it to avoid allocating); returns how
    /// many samples were appended.
    pub fn wait_into(&mut self, timeout: Duration, out: &mut Vec<T>) -> Result<usize, ShmError> {
        let deadline = Instant::now() + timeout;
        loop {
            // Drain first: a notification that arrived before we sleep is latched by the
            // listener, so no wake-up is lost between the drain and the wait.
            let n = self.drain_into(out)?;
            if n > 0 {
                return Ok(n);
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(0);
            }
            match self.listener.timed_wait(|_| {}, deadline - now) {
                Ok(_) => {}
                // A signal handler ran (e.g. the caller's SIGINT flag): return early, like
                // EINTR, so the caller can look at its flags; samples may still be buffered.
                Err(ListenerWaitError::InterruptSignal) => return self.drain_into(out),
                Err(source) => {
                    return Err(ShmError::Wait {
                        service: self.service_name.clone(),
                        source,
                    });
                }
            }
        }
    }

    /// Samples received since [`open`](Self::open).
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Samples missed since [`open`](Self::open), from gaps in `seq` (overwritten because this
    /// subscriber fell behind, or never published); always 0 for [`DaemonStatus`].
    /// A `seq` that goes backwards (a restarted daemon) is not counted.
    pub fn missed(&self) -> u64 {
        self.missed
    }

    /// Publishers currently connected (0 while no daemon runs on this instance).
    pub fn publishers(&self) -> usize {
        self.service.dynamic_config().number_of_publishers()
    }

    fn account(&mut self, sample: &T) {
        self.received += 1;
        if let Some(seq) = sample.seq() {
            match self.last_seq {
                Some(last) if seq > last => self.missed += seq - last - 1,
                _ => {}
            }
            self.last_seq = Some(seq);
        }
    }
}

/// A subscription to a stream chosen at run time (e.g. by a command-line flag).
#[derive(Debug)]
pub enum Subscriber {
    /// `imud/<instance>/raw`.
    Raw(Subscription<RawSample>),
    /// `imud/<instance>/corrected`.
    Corrected(Subscription<CorrectedSample>),
    /// `imud/<instance>/status`.
    Status(Subscription<DaemonStatus>),
}

impl Subscriber {
    /// Opens `stream` of `instance`, waiting up to `open_timeout` for the daemon
    /// (see [`Subscription::open`]).
    pub fn open(
        instance: &str,
        stream: Stream,
        open_timeout: Duration,
    ) -> Result<Subscriber, ShmError> {
        Ok(match stream {
            Stream::Raw => Subscriber::Raw(Subscription::open(instance, open_timeout)?),
            Stream::Corrected => Subscriber::Corrected(Subscription::open(instance, open_timeout)?),
            Stream::Status => Subscriber::Status(Subscription::open(instance, open_timeout)?),
        })
    }

    /// The stream this subscriber reads.
    pub fn stream(&self) -> Stream {
        match self {
            Subscriber::Raw(_) => Stream::Raw,
            Subscriber::Corrected(_) => Stream::Corrected,
            Subscriber::Status(_) => Stream::Status,
        }
    }

    /// The publish-subscribe service this subscriber reads.
    pub fn service_name(&self) -> &str {
        match self {
            Subscriber::Raw(s) => s.service_name(),
            Subscriber::Corrected(s) => s.service_name(),
            Subscriber::Status(s) => s.service_name(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn service_names_follow_the_documented_scheme() {
        let names = ServiceNames::for_instance("default");
        assert_eq!(names.raw, "imud/default/raw");
        assert_eq!(names.corrected, "imud/default/corrected");
        assert_eq!(names.status, "imud/default/status");
        assert_eq!(names.event, "imud/default/event");
        assert_eq!(names.of(Stream::Corrected), "imud/default/corrected");
    }

    #[test]
    fn options_parse_from_kebab_case_with_defaults_and_reject_unknown_keys() {
        let o: ShmOptions = serde_json::from_str(r#"{"subscriber-buffer-size": 8}"#).unwrap();
        assert_eq!(
            o,
            ShmOptions {
                subscriber_buffer_size: 8,
                ..ShmOptions::default()
            }
        );
        assert!(serde_json::from_str::<ShmOptions>(r#"{"buffer": 8}"#).is_err());
    }

    #[test]
    fn event_ids_are_stable() {
        assert_eq!(ShmEvent::Samples.id(), 1);
        assert_eq!(ShmEvent::Status.id(), 2);
    }
}
