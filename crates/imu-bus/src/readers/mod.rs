//! The readers' socket: imud's streams for processes of other users in its readers' group.
//!
//! iceoryx2 0.10 creates every shared-memory segment 0600 and its directories 0750 for their
//! owner, and its only alternative (the build-time `dev_permissions` feature) makes everything
//! world read-write; its subscribers also write shared state (the dynamic config, connections,
//! event sockets). So iceoryx2 cannot give "members of a group read, only imud writes". imud
//! therefore also serves its streams on a Unix `SOCK_SEQPACKET` socket (`[publish]
//! readers-socket`, by default `/run/imud/<instance>/readers.sock`), in a directory only imud may
//! write, mode 0660 and group `[publish] group`: the kernel lets members connect and refuses
//! everyone else (`EACCES`), and only imud's process is on the sending end. A client checks the
//! server's user with `SO_PEERCRED` (the kernel's record of who called `listen`), so a socket of
//! another user placed anywhere is refused ([`ReadersClient::connect`]).
//!
//! # Packets
//!
//! Every packet is one record of one stream: a 16-byte header, then the record in the C layout
//! of its shared-memory type ([`crate::sample`], encoded by [`WireRecord`]); all numbers
//! little-endian.
//! ```text
//!  0 u8[4] magic "IMRD"     4 u16 version (1)       6 u8 stream (1 raw, 2 corrected,
//!  7 u8    reserved (0)     8 u64 dropped                3 status, 4 health)
//! 16 record: 176 (raw), 128 (corrected), 208 (status) or 176 (health) bytes
//! ```
//! A record's length tells its layout: a status of 168 bytes (`imud::DaemonStatus.v3`, from an
//! imud before the time sync) is read with the time sync unknown (source `device`, state
//! `none`, NaN, 0), so a newer client reads an older imud.
//! `dropped` is how many packets the server could not queue for this connection so far (its
//! socket buffer was full: the server never waits for a reader); a reader also sees lost samples
//! as gaps in `seq` ([`ReadersClient::missed`]).

use std::fmt;
use std::io::{ErrorKind, Read};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use socket2::{Domain, SockAddr, Socket, Type};

use crate::sample::{CalibrationHealth, CorrectedSample, DaemonStatus, RawSample};
use crate::shm::{ProcessIdentity, TrustedPublishers, UserId};

mod records;

pub use records::WireRecord;

/// The first four bytes of every packet.
pub const MAGIC: [u8; 4] = *b"IMRD";
/// The packet layout version this build reads and writes.
pub const VERSION: u16 = 1;
/// Bytes of the packet header.
pub const HEADER_LEN: usize = 16;
/// The largest packet (a header and the largest record).
pub const MAX_PACKET_LEN: usize = HEADER_LEN + 208;
/// The socket file's name under `/run/imud/<instance>/`.
pub const SOCKET_FILE_NAME: &str = "readers.sock";

/// The default socket of `instance`: `/run/imud/<instance>/readers.sock`.
pub fn default_socket_path(instance: &str) -> PathBuf {
    Path::new("/run/imud").join(instance).join(SOCKET_FILE_NAME)
}

/// Writes the packet carrying `record` into `out` (replacing its contents), with `dropped` 0;
/// the server sets each connection's count with [`set_dropped`].
pub fn encode_packet<T: WireRecord>(record: &T, out: &mut Vec<u8>) {
    out.clear();
    out.resize(HEADER_LEN + T::SIZE, 0);
    out[..4].copy_from_slice(&MAGIC);
    out[4..6].copy_from_slice(&VERSION.to_le_bytes());
    out[6] = T::CODE;
    record.encode(&mut out[HEADER_LEN..]);
}

/// Sets the `dropped` field of a packet made by [`encode_packet`].
pub fn set_dropped(packet: &mut [u8], dropped: u64) {
    packet[8..16].copy_from_slice(&dropped.to_le_bytes());
}

/// A record received on the readers' socket.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Received {
    /// A raw sample.
    Raw(RawSample),
    /// A corrected sample.
    Corrected(CorrectedSample),
    /// A daemon status.
    Status(DaemonStatus),
    /// A calibration health report.
    Health(CalibrationHealth),
}

impl Received {
    /// The daemon's sequence number, for the sample streams.
    pub fn seq(&self) -> Option<u64> {
        match self {
            Received::Raw(r) => Some(r.seq),
            Received::Corrected(c) => Some(c.seq),
            Received::Status(_) | Received::Health(_) => None,
        }
    }
}

/// A packet that is not one this build understands.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// Shorter than a header.
    #[error("{len}-byte packet is shorter than the {HEADER_LEN}-byte header")]
    Short {
        /// Its length.
        len: usize,
    },
    /// Not an imud readers' packet.
    #[error("bad magic {found:02x?} (expected \"IMRD\"): not an imud readers' socket")]
    Magic {
        /// The first four bytes.
        found: [u8; 4],
    },
    /// Another layout version.
    #[error(
        "packet version {found} (this build reads {VERSION}): use matching imud and client builds"
    )]
    Version {
        /// The version in the packet.
        found: u16,
    },
    /// An unknown stream code.
    #[error("unknown stream code {code} (1 raw, 2 corrected, 3 status, 4 health)")]
    Stream {
        /// The code.
        code: u8,
    },
    /// The record's length does not match its stream's.
    #[error(
        "stream {code} carries {expected}-byte records, the packet has {found} bytes after the header"
    )]
    Length {
        /// The stream code.
        code: u8,
        /// Its record size.
        expected: usize,
        /// What the packet holds.
        found: usize,
    },
}

/// Decodes one packet: the connection's `dropped` count and the record.
pub fn decode_packet(packet: &[u8]) -> Result<(u64, Received), PacketError> {
    if packet.len() < HEADER_LEN {
        return Err(PacketError::Short { len: packet.len() });
    }
    let magic: [u8; 4] = packet[..4].try_into().unwrap_or_default();
    if magic != MAGIC {
        return Err(PacketError::Magic { found: magic });
    }
    let version = u16::from_le_bytes([packet[4], packet[5]]);
    if version != VERSION {
        return Err(PacketError::Version { found: version });
    }
    let code = packet[6];
    let mut dropped = [0u8; 8];
    dropped.copy_from_slice(&packet[8..16]);
    let dropped = u64::from_le_bytes(dropped);
    let body = &packet[HEADER_LEN..];
    fn record<T: WireRecord>(code: u8, body: &[u8]) -> Result<T, PacketError> {
        if body.len() == T::SIZE {
            Ok(T::decode(body))
        } else {
            Err(PacketError::Length {
                code,
                expected: T::SIZE,
                found: body.len(),
            })
        }
    }
    let received = match code {
        RawSample::CODE => Received::Raw(record(code, body)?),
        CorrectedSample::CODE => Received::Corrected(record(code, body)?),
        DaemonStatus::CODE if body.len() == records::DAEMON_STATUS_V3_SIZE => {
            Received::Status(records::decode_status_v3(body))
        }
        DaemonStatus::CODE => Received::Status(record(code, body)?),
        CalibrationHealth::CODE => Received::Health(record(code, body)?),
        _ => return Err(PacketError::Stream { code }),
    };
    Ok((dropped, received))
}

/// Errors of a readers' socket client. Each names the socket path.
#[derive(Debug, thiserror::Error)]
pub enum ReadersError {
    /// No server listened on the path within the wait.
    #[error(
        "no imud serves readers at {} (waited {:.1} s): is imud running with [publish] \
         readers-socket (or group) set?",
        .path.display(), .waited.as_secs_f64()
    )]
    NotRunning {
        /// The socket path.
        path: PathBuf,
        /// How long the client waited.
        waited: Duration,
    },
    /// The kernel refused the connection: this user may not write the socket file.
    #[error(
        "permission denied connecting to {} (owned by {owner}, group {group}, mode {mode:o}): \
         this user is not in the socket's group; add it to that group (e.g. `usermod -aG \
         {group} USER`, then log in again)",
        .path.display()
    )]
    Denied {
        /// The socket path.
        path: PathBuf,
        /// The socket file's owner.
        owner: UserId,
        /// The socket file's group name (or gid).
        group: String,
        /// The socket file's permission bits.
        mode: u32,
    },
    /// Connecting failed otherwise.
    #[error("cannot connect to the imud readers' socket {}", .path.display())]
    Connect {
        /// The socket path.
        path: PathBuf,
        /// The system error.
        #[source]
        source: std::io::Error,
    },
    /// The server is not a user the client trusts.
    #[error(
        "the readers' socket {} is served by {server}, which is not a trusted imud publisher \
         (trusted: {trusted}); refusing its samples (pass the daemon's user with \
         --publisher-user if this is the imud you expect)",
        .path.display()
    )]
    UntrustedServer {
        /// The socket path.
        path: PathBuf,
        /// The serving process, as the kernel reports it.
        server: ProcessIdentity,
        /// The trusted users, for the message.
        trusted: String,
    },
    /// Receiving failed.
    #[error("cannot receive from the readers' socket {}", .path.display())]
    Receive {
        /// The socket path.
        path: PathBuf,
        /// The system error.
        #[source]
        source: std::io::Error,
    },
    /// The server sent a packet this build does not understand.
    #[error("bad packet on the readers' socket {}", .path.display())]
    Packet {
        /// The socket path.
        path: PathBuf,
        /// What is wrong with it.
        #[source]
        source: PacketError,
    },
    /// The server closed the connection (imud stopped).
    #[error("imud closed the readers' socket {} (it stopped or restarted)", .path.display())]
    Closed {
        /// The socket path.
        path: PathBuf,
    },
}

/// How long the client sleeps between attempts to connect to a socket that is not there yet.
const CONNECT_RETRY_PERIOD: Duration = Duration::from_millis(50);

/// A connection to imud's readers' socket, its server checked.
pub struct ReadersClient {
    path: PathBuf,
    socket: Socket,
    server: ProcessIdentity,
    timeout: Option<Duration>,
    buf: Vec<u8>,
    dropped: u64,
    received: u64,
    missed: u64,
    last_seq: [Option<u64>; 2],
}

impl fmt::Debug for ReadersClient {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ReadersClient")
            .field("path", &self.path)
            .field("server", &self.server)
            .field("received", &self.received)
            .finish_non_exhaustive()
    }
}

impl ReadersClient {
    /// Connects to the socket at `path` (waiting up to `wait` for it to appear) and checks with
    /// `SO_PEERCRED` that the process serving it runs as a user in `trusted`.
    pub fn connect(
        path: &Path,
        trusted: &TrustedPublishers,
        wait: Duration,
    ) -> Result<ReadersClient, ReadersError> {
        let started = Instant::now();
        let socket = loop {
            match try_connect(path) {
                Ok(socket) => break socket,
                Err(e)
                    if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::ConnectionRefused)
                        && started.elapsed() < wait =>
                {
                    std::thread::sleep(CONNECT_RETRY_PERIOD);
                }
                Err(e)
                    if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::ConnectionRefused) =>
                {
                    return Err(ReadersError::NotRunning {
                        path: path.to_owned(),
                        waited: started.elapsed(),
                    });
                }
                Err(e) if e.kind() == ErrorKind::PermissionDenied => {
                    return Err(denied(path, e));
                }
                Err(source) => {
                    return Err(ReadersError::Connect {
                        path: path.to_owned(),
                        source,
                    });
                }
            }
        };
        let cred =
            nix::sys::socket::getsockopt(&socket, nix::sys::socket::sockopt::PeerCredentials)
                .map_err(|e| ReadersError::Connect {
                    path: path.to_owned(),
                    source: e.into(),
                })?;
        let server = ProcessIdentity {
            pid: cred.pid(),
            user: Some(UserId(cred.uid())),
        };
        if !trusted.contains(UserId(cred.uid())) {
            return Err(ReadersError::UntrustedServer {
                path: path.to_owned(),
                server,
                trusted: trusted.to_string(),
            });
        }
        Ok(ReadersClient {
            path: path.to_owned(),
            socket,
            server,
            timeout: None,
            buf: vec![0; MAX_PACKET_LEN + 1],
            dropped: 0,
            received: 0,
            missed: 0,
            last_seq: [None; 2],
        })
    }

    /// The socket path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The serving process and its user, as the kernel reported them at connection.
    pub fn server(&self) -> ProcessIdentity {
        self.server
    }

    /// The next record, or `None` when none came within `timeout` (or a signal interrupted
    /// the wait).
    pub fn recv(&mut self, timeout: Duration) -> Result<Option<Received>, ReadersError> {
        if self.timeout != Some(timeout) {
            // A zero timeout would mean "block forever" to the kernel.
            let t = timeout.max(Duration::from_micros(1));
            self.socket
                .set_read_timeout(Some(t))
                .map_err(|source| self.receive_error(source))?;
            self.timeout = Some(timeout);
        }
        let n = match (&self.socket).read(&mut self.buf) {
            Ok(0) => {
                return Err(ReadersError::Closed {
                    path: self.path.clone(),
                });
            }
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) =>
            {
                return Ok(None);
            }
            Err(source) => return Err(self.receive_error(source)),
        };
        let (dropped, received) =
            decode_packet(&self.buf[..n]).map_err(|source| ReadersError::Packet {
                path: self.path.clone(),
                source,
            })?;
        self.dropped = dropped;
        self.received += 1;
        let slot = match received {
            Received::Raw(_) => Some(0),
            Received::Corrected(_) => Some(1),
            _ => None,
        };
        if let (Some(slot), Some(seq)) = (slot, received.seq()) {
            if let Some(last) = self.last_seq[slot]
                && seq > last + 1
            {
                self.missed += seq - last - 1;
            }
            self.last_seq[slot] = Some(seq);
        }
        Ok(Some(received))
    }

    /// Records received so far (all streams).
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Raw and corrected samples missed (gaps in `seq`) since the first of each.
    pub fn missed(&self) -> u64 {
        self.missed
    }

    /// Packets the server could not queue for this connection, as of the last packet.
    pub fn server_dropped(&self) -> u64 {
        self.dropped
    }

    fn receive_error(&self, source: std::io::Error) -> ReadersError {
        ReadersError::Receive {
            path: self.path.clone(),
            source,
        }
    }
}

fn try_connect(path: &Path) -> std::io::Result<Socket> {
    let socket = Socket::new(Domain::UNIX, Type::SEQPACKET, None)?;
    socket.connect(&SockAddr::unix(path)?)?;
    Ok(socket)
}

/// The permission error, with the socket file's owner, group and mode for the message.
fn denied(path: &Path, source: std::io::Error) -> ReadersError {
    match std::fs::metadata(path) {
        Ok(m) => ReadersError::Denied {
            path: path.to_owned(),
            owner: UserId(m.uid()),
            group: nix::unistd::Group::from_gid(nix::unistd::Gid::from_raw(m.gid()))
                .ok()
                .flatten()
                .map_or_else(|| m.gid().to_string(), |g| g.name),
            mode: m.mode() & 0o7777,
        },
        // A directory on the way is closed to us: no details to give.
        Err(_) => ReadersError::Connect {
            path: path.to_owned(),
            source,
        },
    }
}

#[cfg(test)]
mod tests;
