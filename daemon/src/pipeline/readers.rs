//! The readers' socket server: imud's streams for processes of its readers' group (see
//! `imu_bus::readers` for the packets and why iceoryx2 cannot serve them).
//!
//! The socket is bound under a temporary name in a directory only this user may write, given
//! mode 0660 (0600 without a group) and the readers' group, and then renamed over the path, so
//! it is never reachable with looser permissions and a stale socket of a previous run is
//! replaced atomically. An accept thread checks nothing (the kernel already refused anyone
//! outside the group) and hands connections to the data path, which sends every record with
//! `MSG_DONTWAIT`: a full connection loses the packet (counted, and told to the reader in the
//! next packet's header), a closed one is removed. The data path never waits for a reader.

use std::os::unix::fs::{DirBuilderExt, FileTypeExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender};
use std::thread::JoinHandle;

use imu_bus::readers::{WireRecord, encode_packet, set_dropped};
use nix::sys::socket::MsgFlags;
use socket2::{Domain, SockAddr, Socket, Type};
use tracing::{info, warn};

/// Connections waiting in the kernel before the accept thread takes them.
const LISTEN_BACKLOG: i32 = 16;

/// Send buffer asked for per connection: about 2 s of raw and corrected packets at 1 kHz (the
/// kernel caps it at `net.core.wmem_max`).
const SEND_BUFFER_BYTES: usize = 4 << 20;

/// Errors setting up the readers' socket; each names the path and what to do.
#[derive(Debug, thiserror::Error)]
pub enum ReadersServerError {
    /// A directory on the way could be changed by another user.
    #[error(
        "the readers' socket directory {} is not safe: {problem}; only imud's user (or root) may \
         write it and every directory above it, so no one else can place or replace the socket \
         (use a RuntimeDirectory= under systemd, or another [publish] readers-socket)",
        .dir.display()
    )]
    UnsafeDirectory {
        /// The directory.
        dir: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// The configured group does not exist.
    #[error(
        "[publish] group {group:?} does not exist (the sysusers file creates imud-readers: \
         systemd-sysusers, or groupadd --system {group})"
    )]
    NoSuchGroup {
        /// The group name.
        group: String,
    },
    /// imud's user may not give the socket to the group.
    #[error(
        "cannot give the readers' socket {} to group {group:?}: imud's user must be a member of \
         it (sysusers: `m imud {group}`, or usermod -aG {group} USER)",
        .path.display()
    )]
    NotInGroup {
        /// The socket path.
        path: PathBuf,
        /// The group name.
        group: String,
        /// The system error.
        #[source]
        source: std::io::Error,
    },
    /// Something else than a socket is at the path.
    #[error("{} exists and is not a socket; refusing to replace it", .path.display())]
    NotASocket {
        /// The path.
        path: PathBuf,
    },
    /// A live process serves the socket already (another imud of the same instance).
    #[error(
        "{} is served by a running process (pid {pid}, uid {uid}): another imud with this \
         instance's readers' socket? stop it or choose another [publish] readers-socket",
        .path.display()
    )]
    AlreadyServed {
        /// The path.
        path: PathBuf,
        /// The serving process, as the kernel reports it.
        pid: i32,
        /// Its user.
        uid: u32,
    },
    /// A system call failed.
    #[error("cannot {what} {}", .path.display())]
    Io {
        /// What was being done.
        what: &'static str,
        /// The path.
        path: PathBuf,
        /// The system error.
        #[source]
        source: std::io::Error,
    },
}

fn io(what: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> ReadersServerError {
    let path = path.to_owned();
    move |source| ReadersServerError::Io { what, path, source }
}

/// One reader's connection.
struct Connection {
    socket: Socket,
    /// Packets this connection could not take (its buffer was full).
    dropped: u64,
    /// The reader's pid, for the log.
    pid: i32,
}

/// The readers' socket of a running daemon.
pub struct ReadersServer {
    path: PathBuf,
    ino: u64,
    listener: Arc<Socket>,
    incoming: Receiver<Connection>,
    accept_thread: Option<JoinHandle<()>>,
    connections: Vec<Connection>,
    packet: Vec<u8>,
    drops: u64,
}

impl std::fmt::Debug for ReadersServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReadersServer")
            .field("path", &self.path)
            .field("connections", &self.connections.len())
            .field("drops", &self.drops)
            .finish_non_exhaustive()
    }
}

impl ReadersServer {
    /// Creates the socket at `path` (and its missing directories, mode 0755), readable and
    /// writable by `group`'s members when given (mode 0660), else by this user only (0600).
    pub fn open(path: &Path, group: Option<&str>) -> Result<ReadersServer, ReadersServerError> {
        let gid = group
            .map(|g| match nix::unistd::Group::from_name(g) {
                Ok(Some(found)) => Ok(found.gid.as_raw()),
                _ => Err(ReadersServerError::NoSuchGroup {
                    group: g.to_owned(),
                }),
            })
            .transpose()?;
        let name = path.file_name().ok_or_else(|| ReadersServerError::Io {
            what: "use as a socket path (no file name)",
            path: path.to_owned(),
            source: std::io::ErrorKind::InvalidInput.into(),
        })?;
        let parent = path.parent().unwrap_or(Path::new("."));
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o755)
            .create(parent)
            .map_err(io("create the directory", parent))?;
        let dir = parent
            .canonicalize()
            .map_err(io("resolve the directory", parent))?;
        check_safe_directory(&dir)?;
        let path = dir.join(name);
        match std::fs::symlink_metadata(&path) {
            Ok(m) if !m.file_type().is_socket() => {
                return Err(ReadersServerError::NotASocket { path });
            }
            // A socket someone still listens on is not stale: refuse rather than steal it.
            Ok(_) => {
                if let Some((pid, uid)) = live_server(&path) {
                    return Err(ReadersServerError::AlreadyServed { path, pid, uid });
                }
            }
            Err(_) => {}
        }

        let tmp = dir.join(format!(
            ".{}.{}.tmp",
            name.to_string_lossy(),
            std::process::id()
        ));
        let _ = std::fs::remove_file(&tmp);
        let listener = Socket::new(Domain::UNIX, Type::SEQPACKET, None)
            .map_err(io("create a socket for", &path))?;
        let addr = SockAddr::unix(&tmp).map_err(io("use as a socket path", &tmp))?;
        listener.bind(&addr).map_err(io("bind", &tmp))?;
        let placed = (|| -> Result<u64, ReadersServerError> {
            let mode = if gid.is_some() { 0o660 } else { 0o600 };
            std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(mode))
                .map_err(io("set the mode of", &tmp))?;
            if let (Some(gid), Some(group)) = (gid, group) {
                std::os::unix::fs::chown(&tmp, None, Some(gid)).map_err(|source| {
                    ReadersServerError::NotInGroup {
                        path: path.clone(),
                        group: group.to_owned(),
                        source,
                    }
                })?;
            }
            // SO_PEERCRED reports the credentials of the process that called listen().
            listener
                .listen(LISTEN_BACKLOG)
                .map_err(io("listen on", &tmp))?;
            std::fs::rename(&tmp, &path).map_err(io("move the socket to", &path))?;
            std::fs::metadata(&path)
                .map(|m| m.ino())
                .map_err(io("inspect", &path))
        })();
        let ino = match placed {
            Ok(ino) => ino,
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                return Err(e);
            }
        };

        let listener = Arc::new(listener);
        let (tx, incoming) = std::sync::mpsc::channel();
        let accept_thread = std::thread::Builder::new()
            .name("imud-readers".into())
            .spawn({
                let listener = Arc::clone(&listener);
                move || accept_loop(&listener, &tx)
            })
            .map_err(io("start the accept thread of", &path))?;
        info!(
            "serving readers on {} (group {})",
            path.display(),
            group.unwrap_or("none: this user only")
        );
        Ok(ReadersServer {
            path,
            ino,
            listener,
            incoming,
            accept_thread: Some(accept_thread),
            connections: Vec::new(),
            packet: Vec::with_capacity(imu_bus::readers::MAX_PACKET_LEN),
            drops: 0,
        })
    }

    /// The socket's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sends `record` to every connected reader without waiting: a full connection loses it
    /// (counted), a closed one is removed.
    pub fn send<T: WireRecord>(&mut self, record: &T) {
        // New connections from the accept thread (a disconnected channel means it stopped).
        while let Ok(c) = self.incoming.try_recv() {
            self.connections.push(c);
        }
        if self.connections.is_empty() {
            return;
        }
        encode_packet(record, &mut self.packet);
        let flags = (MsgFlags::MSG_DONTWAIT | MsgFlags::MSG_NOSIGNAL).bits();
        let packet = &mut self.packet;
        let drops = &mut self.drops;
        self.connections.retain_mut(|c| {
            set_dropped(packet, c.dropped);
            match c.socket.send_with_flags(packet, flags) {
                Ok(_) => true,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted
                    ) || e.raw_os_error() == Some(nix::libc::ENOBUFS) =>
                {
                    c.dropped += 1;
                    *drops += 1;
                    true
                }
                Err(e) => {
                    info!(
                        "reader pid {} went away ({e}); {} packets dropped for it",
                        c.pid, c.dropped
                    );
                    false
                }
            }
        });
    }

    /// Readers connected (as of the last [`send`](Self::send)).
    pub fn connections(&self) -> usize {
        self.connections.len()
    }

    /// Packets not delivered because a reader's connection was full, all readers together.
    pub fn drops(&self) -> u64 {
        self.drops
    }
}

impl Drop for ReadersServer {
    fn drop(&mut self) {
        // Wakes the blocked accept (Linux returns EINVAL from accept on a shut-down listener).
        let _ = self.listener.shutdown(std::net::Shutdown::Both);
        if let Some(t) = self.accept_thread.take() {
            let _ = t.join();
        }
        // Remove the socket only if it is still ours (not a newer run's).
        if std::fs::metadata(&self.path).is_ok_and(|m| m.ino() == self.ino) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// The pid and uid of the process listening on the socket at `path`, if one does.
fn live_server(path: &Path) -> Option<(i32, u32)> {
    let probe = Socket::new(Domain::UNIX, Type::SEQPACKET, None).ok()?;
    probe.connect(&SockAddr::unix(path).ok()?).ok()?;
    let cred =
        nix::sys::socket::getsockopt(&probe, nix::sys::socket::sockopt::PeerCredentials).ok()?;
    Some((cred.pid(), cred.uid()))
}

/// Takes connections until the listener is shut down.
fn accept_loop(listener: &Socket, tx: &Sender<Connection>) {
    loop {
        match listener.accept() {
            Ok((socket, _)) => {
                let pid = nix::sys::socket::getsockopt(
                    &socket,
                    nix::sys::socket::sockopt::PeerCredentials,
                )
                .map_or(0, |c| c.pid());
                // Best effort: a bigger buffer rides out a reader's short stalls.
                let _ = socket.set_send_buffer_size(SEND_BUFFER_BYTES);
                info!("reader pid {pid} connected");
                if tx
                    .send(Connection {
                        socket,
                        dropped: 0,
                        pid,
                    })
                    .is_err()
                {
                    return;
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => return,
            Err(e) => {
                warn!("readers' socket: accept failed: {e}");
                // Out of file descriptors and the like: do not spin.
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
        }
    }
}

/// Checks that `dir` (canonical) and every directory above it can be changed by no one but
/// this user and root: `dir` itself owned by this user (or root) and writable by no group or
/// other; those above either the same or sticky (like /tmp, where no one may rename another
/// user's entry).
fn check_safe_directory(dir: &Path) -> Result<(), ReadersServerError> {
    let me = nix::unistd::geteuid().as_raw();
    let mut current = Some(dir);
    while let Some(d) = current {
        let m = std::fs::metadata(d).map_err(io("inspect", d))?;
        let unsafe_dir = |problem: String| ReadersServerError::UnsafeDirectory {
            dir: d.to_owned(),
            problem,
        };
        if m.uid() != me && m.uid() != 0 {
            return Err(unsafe_dir(format!("it belongs to uid {}", m.uid())));
        }
        let writable_by_others = m.mode() & 0o022 != 0;
        let sticky = m.mode() & 0o1000 != 0;
        if writable_by_others && (d == dir || !sticky) {
            return Err(unsafe_dir(format!(
                "its mode {:o} lets others write it",
                m.mode() & 0o7777
            )));
        }
        current = d.parent();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use imu_bus::CorrectedSample;
    use imu_bus::readers::{ReadersClient, Received};
    use imu_bus::shm::TrustedPublishers;
    use std::time::Duration;

    #[test]
    fn a_reader_gets_every_record_and_a_stale_socket_is_replaced() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
        let path = tmp.path().join("run/inst/readers.sock");
        // A stale socket of a previous run (bound, never removed) is replaced.
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let stale = Socket::new(Domain::UNIX, Type::SEQPACKET, None).unwrap();
        stale.bind(&SockAddr::unix(&path).unwrap()).unwrap();
        drop(stale);
        let mut server = ReadersServer::open(&path, None).unwrap();
        let mode = std::fs::metadata(&path).unwrap().mode();
        assert_eq!(mode & 0o777, 0o600);

        let trusted = TrustedPublishers::default_for_this_process();
        let mut client = ReadersClient::connect(&path, &trusted, Duration::ZERO).unwrap();
        // The accept thread hands the connection over asynchronously: send until it arrives.
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        let mut seq = 0;
        while server.connections() == 0 {
            assert!(std::time::Instant::now() < deadline, "no connection");
            server.send(&CorrectedSample {
                seq,
                ..CorrectedSample::default()
            });
            seq += 1;
            std::thread::yield_now();
        }
        let first = seq - 1;
        for s in seq..seq + 100 {
            server.send(&CorrectedSample {
                seq: s,
                ..CorrectedSample::default()
            });
        }
        let mut got = Vec::new();
        while got.len() < 101 {
            match client.recv(Duration::from_secs(10)).unwrap() {
                Some(Received::Corrected(c)) => got.push(c.seq),
                other => panic!("unexpected {other:?}"),
            }
        }
        assert_eq!(got, (first..seq + 100).collect::<Vec<_>>());
        assert_eq!(client.missed(), 0);
        assert_eq!(server.drops(), 0);

        // A reader that goes away is removed at the next send.
        drop(client);
        server.send(&CorrectedSample::default());
        assert_eq!(server.connections(), 0);
        drop(server);
        assert!(!path.exists(), "the socket is removed on shutdown");
    }

    #[test]
    fn a_slow_reader_loses_packets_counted_on_both_sides_and_a_live_socket_is_not_stolen() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("readers.sock");
        let mut server = ReadersServer::open(&path, None).unwrap();
        // A second server on the same path refuses, naming this process.
        let err = ReadersServer::open(&path, None).unwrap_err();
        assert!(
            matches!(err, ReadersServerError::AlreadyServed { pid, .. }
                if pid == std::process::id() as i32),
            "{err}"
        );
        let trusted = TrustedPublishers::default_for_this_process();
        let mut client = ReadersClient::connect(&path, &trusted, Duration::ZERO).unwrap();
        // The accept thread hands the connection over asynchronously: send until one arrives.
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        loop {
            assert!(std::time::Instant::now() < deadline, "no connection");
            server.send(&CorrectedSample::default());
            if client.recv(Duration::from_millis(1)).unwrap().is_some() {
                break;
            }
        }
        // (The refused server's probe connection is closed and gone by now.)
        assert_eq!(server.connections(), 1);
        // Drain what reached the client before the counted run starts.
        while client.recv(Duration::from_millis(1)).unwrap().is_some() {}
        let before = (client.received(), server.drops());
        // The client reads nothing while the server sends far more than a socket buffer holds.
        const SENT: u64 = 20_000;
        for seq in 1..=SENT {
            server.send(&CorrectedSample {
                seq,
                ..CorrectedSample::default()
            });
        }
        let dropped = server.drops() - before.1;
        assert!(dropped > 0, "the socket buffer never filled");
        // Everything queued is there at once (unix sockets queue at the receiver on send).
        while client.recv(Duration::from_millis(1)).unwrap().is_some() {}
        let received = client.received() - before.0;
        assert_eq!(received + dropped, SENT);
        // One more, after the drain: it arrives and tells the reader every drop, and the seq
        // gaps account for each one.
        server.send(&CorrectedSample {
            seq: SENT + 1,
            ..CorrectedSample::default()
        });
        let last = client.recv(Duration::from_secs(10)).unwrap();
        assert_eq!(last.and_then(|r| r.seq()), Some(SENT + 1));
        assert_eq!(client.server_dropped(), server.drops());
        assert_eq!(client.missed(), dropped);
    }

    #[test]
    fn a_directory_others_may_write_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o777)).unwrap();
        let err = ReadersServer::open(&tmp.path().join("readers.sock"), None).unwrap_err();
        assert!(
            matches!(err, ReadersServerError::UnsafeDirectory { .. }),
            "{err}"
        );
        assert!(err.to_string().contains("lets others write it"), "{err}");
    }

    #[test]
    fn something_else_at_the_path_is_not_replaced() {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
        let path = tmp.path().join("readers.sock");
        std::fs::write(&path, "keep me").unwrap();
        let err = ReadersServer::open(&path, None).unwrap_err();
        assert!(
            matches!(err, ReadersServerError::NotASocket { .. }),
            "{err}"
        );
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "keep me");
    }

    #[test]
    fn an_unknown_group_is_named() {
        let tmp = tempfile::tempdir().unwrap();
        let err =
            ReadersServer::open(&tmp.path().join("r.sock"), Some("no-such-group-xyz")).unwrap_err();
        assert!(
            err.to_string()
                .contains("\"no-such-group-xyz\" does not exist"),
            "{err}"
        );
    }
}
