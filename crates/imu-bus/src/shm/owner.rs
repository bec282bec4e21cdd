//! Who created a service and who publishes on it, as the kernel says: the owner of the service's
//! static-config file under iceoryx2's root path and the user of the publisher's process
//! (`/proc/<pid>`).
//! iceoryx2 0.10 itself records neither; the daemon uses this to refuse services another user
//! created, and subscribers to refuse a publisher that is not the imud they trust.

use std::fmt;
use std::os::unix::fs::MetadataExt;
use std::path::PathBuf;

use iceoryx2::service::service_hash::ServiceHash;
use nix::unistd::{Uid, User};

use super::*;

/// A user, by uid and (when the system knows it) name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UserId(pub u32);

impl UserId {
    /// The effective user of this process.
    pub fn current() -> UserId {
        UserId(nix::unistd::geteuid().as_raw())
    }

    /// The user called `name`, if the system has one.
    pub fn by_name(name: &str) -> Option<UserId> {
        User::from_name(name)
            .ok()
            .flatten()
            .map(|u| UserId(u.uid.as_raw()))
    }

    /// The user's name, if the system knows the uid.
    pub fn name(self) -> Option<String> {
        User::from_uid(Uid::from_raw(self.0))
            .ok()
            .flatten()
            .map(|u| u.name)
    }
}

impl fmt::Display for UserId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(name) => write!(f, "user {name} (uid {})", self.0),
            None => write!(f, "uid {}", self.0),
        }
    }
}

/// A process on a service: its pid and the user it runs as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProcessIdentity {
    /// Process id.
    pub pid: i32,
    /// The owner of `/proc/<pid>` (the process's effective user); `None` when the process is
    /// gone or hidden from us.
    pub user: Option<UserId>,
}

impl fmt::Display for ProcessIdentity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.user {
            Some(user) => write!(f, "pid {} ({user})", self.pid),
            None => write!(f, "pid {} (user unknown)", self.pid),
        }
    }
}

/// The identity of process `pid`, from the owner of `/proc/<pid>`.
pub(super) fn process_identity(pid: i32) -> ProcessIdentity {
    let user = std::fs::metadata(format!("/proc/{pid}"))
        .ok()
        .map(|m| UserId(m.uid()));
    ProcessIdentity { pid, user }
}

/// The static-config file of the service `name` with `pattern`:
/// `<root-path>/<service directory>/<prefix><hash><suffix>`, with iceoryx2's hash of the name and
/// its global config's paths. (Its dynamic segment in `/dev/shm` is named by a random id, so
/// this file is the one resource whose name follows from the service's.)
pub(super) fn static_config_path(name: &ServiceName, pattern: MessagingPattern) -> PathBuf {
    let global = &Config::global_config().global;
    let hash = ServiceHash::new::<<ipc::Service as iceoryx2::service::Service>::ServiceNameHasher>(
        name, pattern,
    );
    PathBuf::from(global.root_path().to_string())
        .join(global.service.directory.to_string())
        .join(format!(
            "{}{}{}",
            global.prefix,
            hash.as_str(),
            global.service.static_config_storage_suffix
        ))
}

/// Who holds the service `name`: the owner of its static-config file, or, when this user may
/// not even look into the services directory, the owner of that directory (iceoryx2 creates it
/// for its first user only). `None` when the service does not exist.
pub(super) fn service_creator(
    name: &ServiceName,
    pattern: MessagingPattern,
) -> Option<(UserId, PathBuf)> {
    let file = static_config_path(name, pattern);
    match std::fs::metadata(&file) {
        Ok(m) => Some((UserId(m.uid()), file)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(_) => {
            let dir = file.parent()?.to_path_buf();
            std::fs::metadata(&dir).ok().map(|m| (UserId(m.uid()), dir))
        }
    }
}

/// Processes of `user` we can see (at most 8), to name who holds a service.
pub(super) fn processes_of(user: UserId) -> Vec<ProcessIdentity> {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let mut found: Vec<ProcessIdentity> = entries
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<i32>().ok())
        .map(process_identity)
        .filter(|p| p.user == Some(user))
        .collect();
    found.sort_by_key(|p| p.pid);
    found.truncate(8);
    found
}

/// Refuses the service `name` if it exists and another user than this process's created it
/// (the daemon must not share services someone else prepared: their creator could publish into
/// them while the daemon restarts, or feed subscribers).
pub(super) fn refuse_foreign(
    instance: &str,
    service: &str,
    name: &ServiceName,
    pattern: MessagingPattern,
) -> Result<(), ShmError> {
    let me = UserId::current();
    match service_creator(name, pattern) {
        Some((owner, path)) if owner != me => Err(ShmError::ForeignService {
            instance: instance.to_owned(),
            service: service.to_owned(),
            owner,
            path,
            holders: processes_of(owner),
        }),
        _ => Ok(()),
    }
}

/// Formats holders for an error message: `its processes: pid 12 (imud), ...` or a note that
/// none could be seen.
pub(super) fn list_holders(holders: &[ProcessIdentity]) -> String {
    if holders.is_empty() {
        "no process of that user is visible to this one".to_owned()
    } else {
        let list: Vec<String> = holders
            .iter()
            .map(|p| {
                let comm = std::fs::read_to_string(format!("/proc/{}/comm", p.pid))
                    .map(|c| c.trim().to_owned())
                    .unwrap_or_default();
                format!("pid {} ({comm})", p.pid)
            })
            .collect();
        format!("that user's processes: {}", list.join(", "))
    }
}
