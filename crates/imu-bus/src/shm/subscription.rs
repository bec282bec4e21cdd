//! The subscribers' side: a subscription to one stream (opened with retries while the daemon
//! starts), and `Subscriber`, any of the four streams.

use super::*;

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
pub(super) fn open_with_retry<F, R, E>(
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

/// Opens the event service `event` of `instance`, retrying until `deadline` while it does not
/// exist.
fn open_event(
    node: &Node<ipc::Service>,
    instance: &str,
    event: &str,
    started: Instant,
    deadline: Instant,
) -> Result<EventFactory<ipc::Service>, ShmError> {
    let event_name = service_name(event, instance)?;
    open_with_retry(
        instance,
        event,
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
            service: event.to_owned(),
            source: boxed(e),
        },
    })
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

        let service = Self::open_pubsub(&node, instance, &name, started, deadline)?;
        let event = open_event(&node, instance, &names.event, started, deadline)?;

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

    /// Opens the publish-subscribe service `name` of `instance`, retrying until `deadline`
    /// while it does not exist.
    fn open_pubsub(
        node: &Node<ipc::Service>,
        instance: &str,
        name: &str,
        started: Instant,
        deadline: Instant,
    ) -> Result<IpcPubSub<T>, ShmError> {
        let pubsub_name = service_name(name, instance)?;
        open_with_retry(
            instance,
            name,
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
                service: name.to_owned(),
                type_name: T::TYPE_NAME,
            },
            Ok(e) => ShmError::OpenService {
                service: name.to_owned(),
                source: boxed(e),
            },
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
    /// subscriber fell behind, or never published); always 0 for [`DaemonStatus`] and [`CalibrationHealth`].
    /// A `seq` that goes backwards (a restarted daemon) is not counted.
    pub fn missed(&self) -> u64 {
        self.missed
    }

    /// Checks that the service was created by, and is published by, a user in `trusted`;
    /// returns the publishing process (`None` while no daemon publishes, e.g. during a restart:
    /// then only the creator is checked). Call it after [`open`](Self::open) and again
    /// whenever the publisher may have changed (a restart): iceoryx2 itself does not say who
    /// may publish, so this is what keeps another user's samples out.
    pub fn verify_publisher(
        &self,
        trusted: &TrustedPublishers,
    ) -> Result<Option<ProcessIdentity>, ShmError> {
        let name = service_name(&self.service_name, &self.instance)?;
        if let Some((creator, _)) =
            owner::service_creator(&name, MessagingPattern::PublishSubscribe)
            && !trusted.contains(creator)
        {
            return Err(ShmError::UntrustedPublisher {
                service: self.service_name.clone(),
                what: "created by",
                who: creator.to_string(),
                trusted: trusted.to_string(),
            });
        }
        let publisher = publisher_identity(&self.service);
        match publisher {
            Some(ProcessIdentity {
                user: Some(user), ..
            }) if trusted.contains(user) => Ok(publisher),
            None => Ok(None),
            Some(p) => Err(ShmError::UntrustedPublisher {
                service: self.service_name.clone(),
                what: "published by",
                who: p.to_string(),
                trusted: trusted.to_string(),
            }),
        }
    }

    /// Publishers currently connected (0 while no daemon runs on this instance).
    pub fn publishers(&self) -> usize {
        self.service.dynamic_config().number_of_publishers()
    }

    pub(super) fn account(&mut self, sample: &T) {
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

/// The users whose services and samples a subscriber takes as imud's
/// ([`Subscription::verify_publisher`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TrustedPublishers(Vec<UserId>);

impl TrustedPublishers {
    /// Exactly these users.
    pub fn users(users: Vec<UserId>) -> Self {
        TrustedPublishers(users)
    }

    /// The default of a subscriber: root, this process's own user, and the user `imud` (the
    /// shipped unit's) when the system has one. Another user's process is refused.
    pub fn default_for_this_process() -> Self {
        let mut users = vec![UserId(0), UserId::current()];
        users.extend(UserId::by_name("imud"));
        users.dedup();
        TrustedPublishers(users)
    }

    /// Whether `user` is trusted.
    pub fn contains(&self, user: UserId) -> bool {
        self.0.contains(&user)
    }
}

impl fmt::Display for TrustedPublishers {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let list: Vec<String> = self.0.iter().map(ToString::to_string).collect();
        f.write_str(&list.join(", "))
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
    /// `imud/<instance>/health`.
    Health(Subscription<CalibrationHealth>),
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
            Stream::Health => Subscriber::Health(Subscription::open(instance, open_timeout)?),
        })
    }

    /// The stream this subscriber reads.
    pub fn stream(&self) -> Stream {
        match self {
            Subscriber::Raw(_) => Stream::Raw,
            Subscriber::Corrected(_) => Stream::Corrected,
            Subscriber::Status(_) => Stream::Status,
            Subscriber::Health(_) => Stream::Health,
        }
    }

    /// [`Subscription::verify_publisher`] of whichever stream this is.
    pub fn verify_publisher(
        &self,
        trusted: &TrustedPublishers,
    ) -> Result<Option<ProcessIdentity>, ShmError> {
        match self {
            Subscriber::Raw(s) => s.verify_publisher(trusted),
            Subscriber::Corrected(s) => s.verify_publisher(trusted),
            Subscriber::Status(s) => s.verify_publisher(trusted),
            Subscriber::Health(s) => s.verify_publisher(trusted),
        }
    }

    /// The publish-subscribe service this subscriber reads.
    pub fn service_name(&self) -> &str {
        match self {
            Subscriber::Raw(s) => s.service_name(),
            Subscriber::Corrected(s) => s.service_name(),
            Subscriber::Status(s) => s.service_name(),
            Subscriber::Health(s) => s.service_name(),
        }
    }
}
