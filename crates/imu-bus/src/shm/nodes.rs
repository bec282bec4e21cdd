//! iceoryx2 nodes and channels: stale-node cleanup, node and service names, one typed
//! publish-subscribe channel with its event service.

use super::*;

/// Removes the stale resources of every dead iceoryx2 node this process may access and
/// returns how many are gone (removed here or concurrently by another process). Nodes of other
/// users that we may not touch are skipped.
pub(super) fn remove_dead_nodes(config: &Config) -> Result<u64, ShmError> {
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

pub(super) fn node_name(role: &str, instance: &str) -> String {
    format!("{role}-{instance}")
}

pub(super) fn create_node(name: &str) -> Result<Node<ipc::Service>, ShmError> {
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

pub(super) fn service_name(name: &str, instance: &str) -> Result<ServiceName, ShmError> {
    ServiceName::new(name).map_err(|_| ShmError::InvalidInstanceName {
        instance: instance.to_owned(),
    })
}

/// The process publishing on `service` (the first publisher iceoryx2 lists), if any.
pub(super) fn publisher_identity<T: ShmPayload>(service: &IpcPubSub<T>) -> Option<ProcessIdentity> {
    let mut pid = None;
    service.dynamic_config().list_publishers(|details| {
        pid = details
            .node_id
            .pid::<ipc::Service>()
            .ok()
            .map(|p| p.value());
        CallbackProgression::Stop
    });
    pid.map(owner::process_identity)
}

/// One publish-subscribe service with its single publisher.
pub(super) struct Channel<T: ShmPayload> {
    pub(super) name: String,
    pub(super) service: IpcPubSub<T>,
    pub(super) publisher: Publisher<ipc::Service, T, ()>,
}

impl<T: ShmPayload> Channel<T> {
    pub(super) fn open(
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
                holder: publisher_identity(&service),
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
    pub(super) fn publish(&self, sample: &T, drops: &mut u64) -> Result<usize, ShmError> {
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
