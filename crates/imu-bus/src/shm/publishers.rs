//! The daemon's side of the services: one publisher per stream and the event notifier.

use super::*;

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
    health: Channel<CalibrationHealth>,
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
    /// creates the node `imud-<instance>`, opens or creates the five services of `instance` and
    /// a publisher on each.
    ///
    /// Fails with [`ShmError::AlreadyPublishing`] when a live process publishes on the same
    /// instance, and with [`ShmError::ForeignService`] when any of the services exists and
    /// another user created it.
    pub fn open(instance: &str, options: &ShmOptions) -> Result<Publishers, ShmError> {
        quiet_once();
        validate_instance_name(instance)?;
        let names = ServiceNames::for_instance(instance);
        // Before anything is opened: a service another user created is refused, never shared
        // (its creator could publish into it while this daemon restarts, or feed subscribers).
        for (service, pattern) in [
            (&names.event, MessagingPattern::Event),
            (&names.raw, MessagingPattern::PublishSubscribe),
            (&names.corrected, MessagingPattern::PublishSubscribe),
            (&names.status, MessagingPattern::PublishSubscribe),
            (&names.health, MessagingPattern::PublishSubscribe),
        ] {
            owner::refuse_foreign(
                instance,
                service,
                &service_name(service, instance)?,
                pattern,
            )?;
        }
        let stale_nodes_removed = remove_dead_nodes(Config::global_config())?;
        let node = create_node(&node_name("imud", instance))?;

        // The event service first: a subscriber that sees a sample service can open it too.
        let event = node
            .service_builder(&service_name(&names.event, instance)?)
            .event()
            // Every subscription (of any of the four streams) brings a node and a listener.
            .max_listeners(options.max_subscribers * 4)
            .max_nodes(options.max_subscribers * 4 + 1)
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
        let health = Channel::open(&node, instance, &names.health, options)?;
        Ok(Publishers {
            instance: instance.to_owned(),
            names,
            node,
            raw,
            corrected,
            status,
            health,
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

    /// Publishes a calibration health report; returns how many subscribers it reached. Never
    /// blocks; on failure it is counted in [`drops`](Self::drops).
    pub fn publish_health(&mut self, health: &CalibrationHealth) -> Result<usize, ShmError> {
        self.health.publish(health, &mut self.drops)
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
            Stream::Health => self.health.service.dynamic_config().number_of_subscribers(),
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
