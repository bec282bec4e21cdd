//! The virtual serial link: a pseudo-terminal whose slave side is the device path a host opens,
//! and the loop that paces the device's replies onto it.
//!
//! The simulator keeps its own handle on the slave side (in raw mode) for two reasons: the master
//! never sees a hang-up while no host has the port open (a real device keeps talking to an
//! unplugged cable too), and at the end of a scenario it can tell when the host has read the last
//! byte before closing. Time runs in one of two modes:
//! - real time: the scenario clock follows the wall clock from the first data request (from
//!   power-up for a device that powers up streaming), samples go
//!   out at the scenario rate and bytes are paced to the configured baud rate (a 3DM-GX1; a MIP
//!   unit's USB virtual serial port is not paced);
//! - fast: a virtual clock advances one sample period per data reply and bytes go out as fast as
//!   the host reads them, so hours of scenario run in seconds with identical content.
//!
//! In the scenario's dropouts (`Timeline::link_lost_at`) data replies, streamed or polled, are
//! made and their truth written, but their bytes never reach the host.

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::os::fd::AsFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::SyncSender;
use std::time::{Duration, Instant};

use imu_rec::truth::TruthSample;
use nix::fcntl::{FcntlArg, OFlag, fcntl};
use nix::poll::{PollFd, PollFlags, PollTimeout, poll, ppoll};
use nix::pty::{PtyMaster, grantpt, posix_openpt, ptsname_r, unlockpt};
use nix::sys::termios::{SetArg, cfmakeraw, tcgetattr, tcsetattr};
use nix::sys::time::TimeSpec;

use crate::virtual_device::VirtualDevice;

/// Errors setting up the virtual link.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// A pseudo-terminal call failed.
    #[error("cannot create the pseudo-terminal ({step})")]
    Pty {
        /// Which call.
        step: &'static str,
        /// The errno.
        #[source]
        source: nix::Error,
    },
    /// Opening the slave side or creating the symlink failed.
    #[error("{path}: cannot open")]
    Io {
        /// The path involved.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// A created pseudo-terminal: the master the device talks through and the slave path a host opens.
pub struct Pty {
    master: PtyMaster,
    slave: File,
    slave_path: PathBuf,
}

impl Pty {
    /// Opens a new pty pair with the slave in raw mode (no echo, no line editing, 8-bit clean).
    pub fn open() -> Result<Self, LinkError> {
        let pty = |step| move |source| LinkError::Pty { step, source };
        let master = posix_openpt(OFlag::O_RDWR | OFlag::O_NOCTTY).map_err(pty("posix_openpt"))?;
        grantpt(&master).map_err(pty("grantpt"))?;
        unlockpt(&master).map_err(pty("unlockpt"))?;
        let slave_path = PathBuf::from(ptsname_r(&master).map_err(pty("ptsname_r"))?);
        let slave = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(nix::libc::O_NOCTTY | nix::libc::O_NONBLOCK)
            .open(&slave_path)
            .map_err(|source| LinkError::Io {
                path: slave_path.clone(),
                source,
            })?;
        let mut termios = tcgetattr(slave.as_fd()).map_err(pty("tcgetattr"))?;
        cfmakeraw(&mut termios);
        tcsetattr(slave.as_fd(), SetArg::TCSANOW, &termios).map_err(pty("tcsetattr"))?;
        fcntl(&master, FcntlArg::F_SETFL(OFlag::O_NONBLOCK)).map_err(pty("fcntl"))?;
        Ok(Self {
            master,
            slave,
            slave_path,
        })
    }

    /// The device path a host opens (e.g. `/dev/pts/7`).
    pub fn slave_path(&self) -> &Path {
        &self.slave_path
    }

    /// True while bytes the device sent are still waiting in the slave's input queue.
    fn host_has_unread(&self) -> bool {
        let mut fds = [PollFd::new(self.slave.as_fd(), PollFlags::POLLIN)];
        matches!(poll(&mut fds, PollTimeout::ZERO), Ok(n) if n > 0)
            && fds[0]
                .revents()
                .is_some_and(|r| r.contains(PollFlags::POLLIN))
    }
}

/// How the loop keeps time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pacing {
    /// Wall-clock scenario time, bytes paced to the baud rate.
    RealTime,
    /// Virtual time, as fast as the host reads.
    Fast,
}

/// What a run did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkReport {
    /// Bytes written to the host.
    pub bytes_out: u64,
    /// Bytes received from the host.
    pub bytes_in: u64,
    /// Data replies sent (equals the number of truth samples).
    pub data_replies: u64,
    /// Data replies sent before the host's first command (a unit that powers up streaming,
    /// such as an Xsens MTi, streams before its host configures it); `None` while no command
    /// came.
    pub data_replies_before_first_command: Option<u64>,
    /// Host bytes that did not form a valid command.
    pub rejected_command_bytes: u64,
    /// Continuous-mode samples the device could not send because the link was still busy
    /// (real-time mode only: the data rate exceeds what the baud rate carries).
    pub samples_skipped_link_busy: u64,
    /// Data replies the link lost in the scenario's dropouts (their truth is kept).
    pub data_replies_lost: u64,
    /// Scenario time reached, seconds.
    pub scenario_time_s: f64,
    /// True if the scenario ran to its end (false: stopped from outside).
    pub completed: bool,
    /// Simulated unplugs.
    pub unplugs: u64,
    /// Garbage bytes injected on the line.
    pub bytes_injected: u64,
}

/// Settings of the loop.
#[derive(Debug, Clone)]
pub struct LinkOptions {
    /// Real time or fast.
    pub pacing: Pacing,
    /// How long to wait at the end of the scenario for the host to read what was sent.
    pub linger: Duration,
    /// A stable symlink to re-point at the new pty after a simulated unplug.
    pub link: Option<PathBuf>,
    /// Set to a duration in ms to simulate unplugging the device for that long (the pty is
    /// closed, then a new one appears, at the same link path if there is one).
    pub unplug_ms: Arc<AtomicU64>,
    /// Bytes to put on the line between two replies (line-noise testing); taken once.
    pub inject: Arc<std::sync::Mutex<Vec<u8>>>,
}

/// Points `link` at `target`, replacing an older symlink (never a regular file).
pub fn make_link(link: &Path, target: &Path) -> Result<(), LinkError> {
    let err = |source| LinkError::Io {
        path: link.to_path_buf(),
        source,
    };
    match std::fs::symlink_metadata(link) {
        Ok(m) if m.file_type().is_symlink() => std::fs::remove_file(link).map_err(err)?,
        Ok(_) => {
            return Err(err(std::io::Error::new(
                ErrorKind::AlreadyExists,
                "exists and is not a symlink; refusing to replace it",
            )));
        }
        Err(_) => {}
    }
    std::os::unix::fs::symlink(target, link).map_err(err)
}

/// Runs the device on the pty until the scenario ends or `stop` is set. Truth samples go to
/// `truth` in the order their replies were queued.
pub fn run(
    pty: &mut Pty,
    device: &mut VirtualDevice,
    truth: Option<&SyncSender<TruthSample>>,
    options: LinkOptions,
    stop: &Arc<AtomicBool>,
) -> std::io::Result<LinkReport> {
    Loop {
        device,
        truth,
        options,
        out: Vec::with_capacity(64 * 1024),
        origin: None,
        virtual_t_s: 0.0,
        next_sample_t_s: None,
        delayed: Vec::new(),
        baud_tokens: 0.0,
        last_refill: Instant::now(),
        last_input: Instant::now(),
        report: LinkReport::default(),
    }
    .run(pty, stop)
}

struct Loop<'a> {
    device: &'a mut VirtualDevice,
    truth: Option<&'a SyncSender<TruthSample>>,
    options: LinkOptions,
    out: Vec<u8>,
    /// Wall-clock instant of scenario time zero (real-time mode; set by the first data request).
    origin: Option<Instant>,
    /// Scenario time in fast mode.
    virtual_t_s: f64,
    /// Scenario time of the next continuous-mode sample.
    next_sample_t_s: Option<f64>,
    /// Replies the device sends later (capture gyro bias), with their due time.
    delayed: Vec<(Instant, Vec<u8>)>,
    baud_tokens: f64,
    last_refill: Instant,
    /// When the host last sent a byte (to time out half-received commands).
    last_input: Instant,
    report: LinkReport,
}

/// A command whose argument bytes stop arriving for this long is dropped, as a device would.
const COMMAND_TIMEOUT: Duration = Duration::from_millis(100);

/// Output backlog above which a real-time device on a serial line cannot queue another sample.
const BACKLOG_LIMIT_BYTES: usize = 256;
/// The same for a device on a USB virtual serial port (MIP), which sends samples in bursts: a
/// loop that wakes late queues every sample that fell due meanwhile.
const USB_BACKLOG_LIMIT_BYTES: usize = 16 * 1024;
/// Output kept queued ahead in fast mode.
const FAST_AHEAD_BYTES: usize = 16 * 1024;

impl Loop<'_> {
    fn now_s(&mut self, start_clock: bool) -> f64 {
        match self.options.pacing {
            Pacing::Fast => self.virtual_t_s,
            Pacing::RealTime => {
                if self.origin.is_none() && start_clock {
                    self.origin = Some(Instant::now());
                }
                self.origin.map_or(0.0, |o| o.elapsed().as_secs_f64())
            }
        }
    }

    fn finished(&self, t_s: f64) -> bool {
        t_s >= self.device.core().timeline().duration_s()
    }

    fn emit_truth(&mut self, sample: TruthSample) -> std::io::Result<()> {
        self.report.data_replies += 1;
        if let Some(tx) = self.truth {
            tx.send(sample)
                .map_err(|_| std::io::Error::other("truth writer stopped"))?;
        }
        Ok(())
    }

    fn handle_commands(&mut self) -> std::io::Result<()> {
        if self.device.pending_len() > 0 && self.last_input.elapsed() >= COMMAND_TIMEOUT {
            self.report.rejected_command_bytes += self.device.expire_partial();
        }
        while let Some(request) = self.device.next_request() {
            let request = match request {
                Ok(r) => r,
                Err(rejected) => {
                    self.report.rejected_command_bytes += rejected;
                    continue;
                }
            };
            self.report
                .data_replies_before_first_command
                .get_or_insert(self.report.data_replies);
            let is_data = request.is_data();
            let t_s = self.now_s(is_data);
            if is_data && self.finished(t_s) {
                continue;
            }
            let was_streaming = self.device.is_streaming();
            let answer = self.device.handle(request, t_s);
            if is_data && self.options.pacing == Pacing::Fast {
                self.virtual_t_s += self.device.core().sample_period_s();
            }
            if let Some(truth) = answer.truth {
                self.emit_truth(truth)?;
            }
            if is_data && self.device.core().timeline().link_lost_at(t_s) {
                // A dropout: the poll's answer never reaches the host.
                self.report.data_replies_lost += 1;
            } else {
                self.queue_answer(answer.bytes, answer.delay_s);
            }
            match (was_streaming, self.device.is_streaming()) {
                (false, true) => {
                    // The first sample follows the acknowledgement one period later.
                    let t = self.now_s(true);
                    self.next_sample_t_s = Some(t + self.device.core().sample_period_s());
                }
                (true, false) => self.next_sample_t_s = None,
                _ => {}
            }
        }
        Ok(())
    }

    /// Sends a reply now, or after `delay_s` in real time (a slow command).
    fn queue_answer(&mut self, bytes: Vec<u8>, delay_s: f64) {
        if bytes.is_empty() {
            return;
        }
        if delay_s > 0.0 && self.options.pacing == Pacing::RealTime {
            self.delayed
                .push((Instant::now() + Duration::from_secs_f64(delay_s), bytes));
        } else {
            self.out.extend_from_slice(&bytes);
        }
    }

    /// Queues every continuous-mode sample that is due.
    fn stream(&mut self) -> std::io::Result<()> {
        if !self.device.is_streaming() {
            return Ok(());
        }
        let period = self.device.core().sample_period_s();
        while let Some(t) = self.next_sample_t_s {
            if self.finished(t) {
                break;
            }
            match self.options.pacing {
                Pacing::Fast => {
                    if self.out.len() >= FAST_AHEAD_BYTES {
                        break;
                    }
                    self.virtual_t_s = t;
                }
                Pacing::RealTime => {
                    if t > self.now_s(true) {
                        break;
                    }
                    let limit = match self.device.baud() {
                        Some(_) => BACKLOG_LIMIT_BYTES,
                        None => USB_BACKLOG_LIMIT_BYTES,
                    };
                    if self.out.len() > limit {
                        self.report.samples_skipped_link_busy += 1;
                        self.next_sample_t_s = Some(t + period);
                        continue;
                    }
                }
            }
            self.take_injected();
            let before = self.out.len();
            if let Some(truth) = self.device.stream_sample(t, &mut self.out) {
                self.emit_truth(truth)?;
            }
            if self.device.core().timeline().link_lost_at(t) && self.out.len() > before {
                // A dropout: the sample is made (and its truth kept) but never reaches the host.
                self.out.truncate(before);
                self.report.data_replies_lost += 1;
            }
            self.next_sample_t_s = Some(t + period);
            self.report.scenario_time_s = t;
        }
        Ok(())
    }

    /// Appends bytes queued for injection (between frames, never inside one).
    fn take_injected(&mut self) {
        if let Ok(mut q) = self.options.inject.try_lock()
            && !q.is_empty()
        {
            self.report.bytes_injected += q.len() as u64;
            self.out.append(&mut q);
        }
    }

    fn refill_baud(&mut self, baud: u32) {
        let now = Instant::now();
        let bytes_per_s = f64::from(baud) / 10.0;
        self.baud_tokens = (self.baud_tokens
            + now.duration_since(self.last_refill).as_secs_f64() * bytes_per_s)
            .min(64.0);
        self.last_refill = now;
    }

    fn write_out(&mut self, pty: &mut Pty) -> std::io::Result<()> {
        let now = Instant::now();
        let (due, later): (Vec<_>, Vec<_>) = std::mem::take(&mut self.delayed)
            .into_iter()
            .partition(|(at, _)| *at <= now);
        self.delayed = later;
        for (_, bytes) in due {
            self.out.extend_from_slice(&bytes);
        }
        if self.out.is_empty() {
            return Ok(());
        }
        let allowed = match self.options.pacing {
            Pacing::Fast => self.out.len(),
            Pacing::RealTime => match self.device.baud() {
                Some(baud) => {
                    self.refill_baud(baud);
                    (self.baud_tokens as usize).min(self.out.len())
                }
                None => self.out.len(),
            },
        };
        if allowed == 0 {
            return Ok(());
        }
        match pty.master.write(&self.out[..allowed]) {
            Ok(n) => {
                self.out.drain(..n);
                self.report.bytes_out += n as u64;
                if self.options.pacing == Pacing::RealTime && self.device.baud().is_some() {
                    self.baud_tokens -= n as f64;
                }
                Ok(())
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn read_in(&mut self, pty: &mut Pty) -> std::io::Result<()> {
        let mut buf = [0u8; 4096];
        loop {
            match pty.master.read(&mut buf) {
                Ok(0) => return Ok(()),
                Ok(n) => {
                    self.report.bytes_in += n as u64;
                    self.device.push(&buf[..n]);
                    self.last_input = Instant::now();
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Ok(()),
                // EIO: no slave open right now; we hold one, so this is transient.
                Err(e) if e.raw_os_error() == Some(nix::libc::EIO) => return Ok(()),
                Err(e) => return Err(e),
            }
        }
    }

    /// How long poll may sleep before the loop has something to do.
    fn poll_timeout(&mut self) -> Duration {
        let mut wait = Duration::from_millis(50);
        if !self.out.is_empty() && self.options.pacing == Pacing::RealTime {
            wait = wait.min(Duration::from_millis(2));
        }
        if let Some(t) = self.next_sample_t_s {
            match self.options.pacing {
                Pacing::Fast if self.out.len() < FAST_AHEAD_BYTES => wait = Duration::ZERO,
                Pacing::Fast => {}
                Pacing::RealTime => {
                    let dt = (t - self.now_s(true)).max(0.0);
                    wait = wait.min(Duration::from_secs_f64(dt));
                }
            }
        }
        if self.device.pending_len() > 0 {
            wait = wait.min(COMMAND_TIMEOUT.saturating_sub(self.last_input.elapsed()));
        }
        if let Some(at) = self.delayed.iter().map(|(at, _)| *at).min() {
            wait = wait.min(at.saturating_duration_since(Instant::now()));
        }
        wait
    }

    /// Closes the pty (the host sees a hang-up), waits, and opens a new one; the device keeps
    /// its state and the scenario clock keeps running, like an IMU whose USB cable was pulled.
    fn replug(
        &mut self,
        pty: &mut Pty,
        off: Duration,
        stop: &Arc<AtomicBool>,
    ) -> std::io::Result<()> {
        let fresh = Pty::open().map_err(std::io::Error::other)?;
        // The stable path goes first, as udev removes a device's link when it is unplugged: left
        // pointing at the old pty's number, it would lead a host retrying the path into
        // whichever pty reuses that number meanwhile (another simulator's), and its commands
        // onto that device's line.
        if let Some(link) = &self.options.link {
            let _ = std::fs::remove_file(link);
        }
        // Dropping the old pair closes both ends: the host's reads fail from here on.
        let old = std::mem::replace(pty, fresh);
        drop(old);
        self.out.clear();
        self.device.reset_link();
        let until = Instant::now() + off;
        while Instant::now() < until && !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(10));
        }
        if let Some(link) = &self.options.link {
            make_link(link, pty.slave_path()).map_err(std::io::Error::other)?;
        }
        self.report.unplugs += 1;
        Ok(())
    }

    fn run(mut self, pty: &mut Pty, stop: &Arc<AtomicBool>) -> std::io::Result<LinkReport> {
        // Samples leave on time to a few microseconds, not the default 50 us timer slack (best
        // effort: without it they are only later).
        let _ = nix::sys::prctl::set_timerslack(1_000);
        if self.device.is_streaming() {
            // Powered up streaming: the scenario clock starts now, with no host command, and
            // the first sample follows one period later.
            let t = self.now_s(true);
            self.next_sample_t_s = Some(t + self.device.core().sample_period_s());
        }
        let mut end_at: Option<Instant> = None;
        while !stop.load(Ordering::Relaxed) {
            let unplug_ms = self.options.unplug_ms.swap(0, Ordering::Relaxed);
            if unplug_ms > 0 {
                self.replug(pty, Duration::from_millis(unplug_ms), stop)?;
            }
            self.read_in(pty)?;
            self.handle_commands()?;
            self.stream()?;
            self.write_out(pty)?;

            let t = self.next_sample_t_s.unwrap_or_else(|| self.now_s(false));
            // The scenario clock starts with the first data request; before it nothing can end.
            let started = self.origin.is_some() || self.report.data_replies > 0;
            if started && self.finished(t) && self.delayed.is_empty() && self.out.is_empty() {
                let deadline = *end_at.get_or_insert_with(|| Instant::now() + self.options.linger);
                if !pty.host_has_unread() || Instant::now() >= deadline {
                    self.report.completed = true;
                    break;
                }
            }

            let timeout = self.poll_timeout();
            let mut flags = PollFlags::POLLIN;
            if !self.out.is_empty() {
                flags |= PollFlags::POLLOUT;
            }
            let mut fds = [PollFd::new(pty.master.as_fd(), flags)];
            // ppoll, not poll: its timeout is not whole milliseconds. At 1 kHz the next sample is
            // under 1 ms away, which poll rounded to 0: the thread spun a core between samples
            // (and for the last millisecond before each sample at any rate).
            let timeout = TimeSpec::from_duration(timeout.min(Duration::from_millis(50)));
            match ppoll(&mut fds, Some(timeout), None) {
                Ok(_) | Err(nix::Error::EINTR) => {}
                Err(e) => return Err(std::io::Error::from(e)),
            }
            if fds[0]
                .revents()
                .is_some_and(|r| r.contains(PollFlags::POLLHUP))
            {
                // Nobody else has the slave open; avoid spinning while we wait for a host.
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        self.report.scenario_time_s = self.report.scenario_time_s.max(self.now_s(false));
        Ok(self.report)
    }
}
