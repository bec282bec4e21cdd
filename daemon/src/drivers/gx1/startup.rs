//! The 3DM-GX1's start-up sequence as a state machine, built so that no reply can be taken for
//! another request's.
//!
//! The 3DM-GX1's replies echo only the command byte: an EEPROM read (0x28) answers with a value
//! but not its address, so a reply that comes after its time-out looks exactly like the answer to
//! the next read. Every exchange here is therefore *fenced*: before a request the line is drained
//! until quiet and synchronised by a different command (firmware or serial number) whose reply
//! must come back first — the device answers in order, so any late reply is consumed before the
//! fence's. Each GainScale is read until two consecutive reads agree; a failed exchange is tried
//! again (three tries, with growing back-off, a drain and a fence in between) before the
//! configured fallback is used for that gain alone, said once in the log, and recorded in the
//! metadata and the status.
//!
//! The sequence: stop any stream (a blind stop, a pause for bytes in flight, a confirmed stop),
//! firmware, serial number, the three GainScales, one temperature, then (continuous mode) a
//! drain and the start of the stream, proven by its acknowledgement or by samples arriving.
//! Time is passed in; the driver (`mod.rs`) feeds it replies and deadlines.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use imu_proto::command::Command;
use imu_proto::device::{ACCEL_GAIN_SCALE_ADDR, GYRO_GAIN_SCALE_ADDR, MAG_GAIN_SCALE_ADDR};
use imu_proto::reply::Reply;
use tracing::{error, info, warn};

use crate::drivers::{TRIES, back_off};
use crate::pipeline::Gains;

/// Silence that counts as a quiet line.
pub const QUIET: Duration = Duration::from_millis(50);
/// Longest drain before a request (a line that never goes quiet is still streaming).
pub const MAX_DRAIN: Duration = Duration::from_secs(1);
/// The pause after a blind stop for the bytes still in flight (they are discarded).
pub const STOP_PAUSE: Duration = Duration::from_millis(300);
/// Reads of one GainScale before disagreeing values count as a failed read.
const MAX_GAIN_READS: u32 = 5;
/// The GainScales in the order they are read: name and EEPROM address.
const GAIN_WORDS: [(&str, u16); 3] = [
    ("accel", ACCEL_GAIN_SCALE_ADDR),
    ("gyro", GYRO_GAIN_SCALE_ADDR),
    ("mag", MAG_GAIN_SCALE_ADDR),
];

/// A GainScale word the device could have: 0 and 0xFFFF are blank EEPROM.
pub fn plausible_gain_scale(value: u16) -> bool {
    value != 0 && value != u16::MAX
}

/// What the start-up asks of its driver.
#[derive(Debug, Default)]
pub(super) struct Out {
    /// Bytes to write, in order.
    pub tx: VecDeque<Vec<u8>>,
    /// End the decoder's partial frame (a drain found the line quiet).
    pub flush_decoder: bool,
}

/// A drain: wait until the line has been quiet for [`QUIET`], at most [`MAX_DRAIN`].
#[derive(Debug, Clone, Copy)]
struct Drain {
    started: Instant,
    last_input: Option<Instant>,
}

impl Drain {
    fn new(now: Instant) -> Self {
        Self {
            started: now,
            last_input: None,
        }
    }

    fn deadline(&self) -> Instant {
        (self.last_input.unwrap_or(self.started) + QUIET).min(self.started + MAX_DRAIN)
    }
}

/// Where one exchange is.
#[derive(Debug, Clone, Copy)]
enum Phase {
    /// Waiting before the next try.
    Backoff { until: Instant },
    /// Draining the line before the fence.
    Drain(Drain),
    /// A request is out: the fence (`fence: true`) or the command.
    Await { fence: bool, deadline: Instant },
}

/// How an exchange went.
#[derive(Debug)]
enum Progress {
    Pending,
    Done(Reply),
    Failed(anyhow::Error),
}

/// One request: fenced (drain, a fence exchange with another reply code, then the command) or
/// not (the command alone), tried [`TRIES`] times with back-off. The reply is the one to the
/// command, never a late one.
#[derive(Debug)]
struct Exchange {
    cmd: Command,
    fence: Option<Command>,
    tries: u32,
    attempt: u32,
    phase: Phase,
    timeout: Duration,
    last_error: anyhow::Error,
}

impl Exchange {
    /// A fenced exchange of `cmd`, begun at `now`.
    fn fenced(cmd: Command, timeout: Duration, now: Instant) -> Self {
        let fence = if cmd.code() == Command::FirmwareVersion.code() {
            Command::SerialNumber
        } else {
            Command::FirmwareVersion
        };
        Self {
            cmd,
            fence: Some(fence),
            tries: TRIES,
            attempt: 0,
            phase: Phase::Drain(Drain::new(now)),
            timeout,
            last_error: anyhow!("not tried"),
        }
    }

    /// `cmd` alone, one try, sent now.
    fn single(cmd: Command, timeout: Duration, now: Instant, out: &mut Out) -> Self {
        out.tx.push_back(cmd.to_bytes());
        Self {
            cmd,
            fence: None,
            tries: 1,
            attempt: 0,
            phase: Phase::Await {
                fence: false,
                deadline: now + timeout,
            },
            timeout,
            last_error: anyhow!("not tried"),
        }
    }

    fn deadline(&self) -> Instant {
        match self.phase {
            Phase::Backoff { until } => until,
            Phase::Drain(d) => d.deadline(),
            Phase::Await { deadline, .. } => deadline,
        }
    }

    fn on_input(&mut self, now: Instant) {
        if let Phase::Drain(d) = &mut self.phase {
            d.last_input = Some(now);
        }
    }

    fn send(&mut self, fence: bool, now: Instant, out: &mut Out) {
        let cmd = if fence {
            self.fence.unwrap_or(self.cmd)
        } else {
            self.cmd
        };
        out.tx.push_back(cmd.to_bytes());
        self.phase = Phase::Await {
            fence,
            deadline: now + self.timeout,
        };
    }

    fn on_reply(&mut self, reply: &Reply, now: Instant, out: &mut Out) -> Progress {
        match self.phase {
            Phase::Await { fence: true, .. }
                if self.fence.is_some_and(|f| f.code() == reply.code()) =>
            {
                self.send(false, now, out);
                Progress::Pending
            }
            Phase::Await { fence: false, .. } if reply.code() == self.cmd.code() => {
                Progress::Done(*reply)
            }
            _ => Progress::Pending,
        }
    }

    fn on_timeout(&mut self, now: Instant, out: &mut Out) -> Progress {
        if now < self.deadline() {
            return Progress::Pending;
        }
        match self.phase {
            Phase::Backoff { .. } => {
                if self.fence.is_some() {
                    self.phase = Phase::Drain(Drain::new(now));
                } else {
                    self.send(false, now, out);
                }
                Progress::Pending
            }
            Phase::Drain(_) => {
                out.flush_decoder = true;
                self.send(true, now, out);
                Progress::Pending
            }
            Phase::Await { fence, .. } => {
                let code = if fence {
                    self.fence.unwrap_or(self.cmd).code()
                } else {
                    self.cmd.code()
                };
                let e = anyhow!(
                    "no reply to command 0x{code:02X} within {:.1} s",
                    self.timeout.as_secs_f64()
                );
                self.last_error = if fence {
                    e.context("synchronising the line")
                } else {
                    e
                };
                self.attempt += 1;
                if self.attempt >= self.tries {
                    return Progress::Failed(std::mem::replace(
                        &mut self.last_error,
                        anyhow!("failed"),
                    ));
                }
                self.phase = Phase::Backoff {
                    until: now + back_off(self.attempt),
                };
                Progress::Pending
            }
        }
    }
}

/// Where the start-up is.
#[derive(Debug)]
enum Step {
    /// Waiting before a blind stop.
    StopBackoff {
        attempt: u32,
        until: Instant,
    },
    /// A blind stop was sent: bytes in flight are discarded until `until`.
    StopPause {
        attempt: u32,
        until: Instant,
    },
    /// The confirmed stop.
    StopConfirm {
        attempt: u32,
        ex: Exchange,
    },
    Firmware(Exchange),
    Serial(Exchange),
    /// GainScale `index`: `reads` done, the previous plausible value.
    Gain {
        index: usize,
        reads: u32,
        previous: Option<u16>,
        ex: Exchange,
    },
    Temperature(Exchange),
    /// Draining before the stream starts.
    StartDrain(Drain),
    /// Waiting before try `attempt` of the start.
    StartBackoff {
        attempt: u32,
        until: Instant,
    },
    /// The start's request is out.
    Start {
        attempt: u32,
        ex: Exchange,
    },
    /// Done (or failed): nothing more to do.
    Finished,
}

/// What a start-up step ended with.
#[derive(Debug)]
pub(super) enum Outcome {
    /// The device answered: the identity and gains; the session can start. Streaming follows
    /// (continuous mode) before [`Outcome::Streaming`].
    Identified {
        firmware: String,
        serial: String,
        gains: Gains,
    },
    /// Start-up is done.
    Done,
    /// Start-up failed.
    Failed(anyhow::Error),
}

/// The start-up of one session.
#[derive(Debug)]
pub(super) struct Startup {
    step: Step,
    timeout: Duration,
    fallback: Gains,
    /// The data command to stream, or none (polled).
    stream: Option<Command>,
    firmware: u16,
    serial: u16,
    gains: Gains,
    report: Vec<String>,
    stop_error: anyhow::Error,
    start_error: anyhow::Error,
    /// Data readings made since the session was set (samples prove a stream started).
    pub readings: u64,
}

impl Startup {
    /// A start-up begun at `now`: `fallback` gains, replies within `timeout`, and `stream` the
    /// data command to stream (none: the host polls).
    pub fn new(fallback: Gains, timeout: Duration, stream: Option<Command>, now: Instant) -> Self {
        Self {
            step: Step::StopBackoff {
                attempt: 0,
                until: now,
            },
            timeout,
            fallback,
            stream,
            firmware: 0,
            serial: 0,
            gains: fallback,
            report: Vec::with_capacity(3),
            stop_error: anyhow!("not tried"),
            start_error: anyhow!("not tried"),
            readings: 0,
        }
    }

    /// True while bytes from the device are to be discarded (the pause after a blind stop,
    /// whose bytes the port's input buffer would have dropped).
    pub fn discarding(&self) -> bool {
        matches!(self.step, Step::StopPause { .. })
    }

    /// When [`Startup::on_timeout`] is next due.
    pub fn deadline(&self) -> Option<Instant> {
        match &self.step {
            Step::StopBackoff { until, .. }
            | Step::StopPause { until, .. }
            | Step::StartBackoff { until, .. } => Some(*until),
            Step::StopConfirm { ex, .. }
            | Step::Firmware(ex)
            | Step::Serial(ex)
            | Step::Gain { ex, .. }
            | Step::Temperature(ex)
            | Step::Start { ex, .. } => Some(ex.deadline()),
            Step::StartDrain(d) => Some(d.deadline()),
            Step::Finished => None,
        }
    }

    fn exchange(&mut self) -> Option<&mut Exchange> {
        match &mut self.step {
            Step::StopConfirm { ex, .. }
            | Step::Firmware(ex)
            | Step::Serial(ex)
            | Step::Gain { ex, .. }
            | Step::Temperature(ex)
            | Step::Start { ex, .. } => Some(ex),
            _ => None,
        }
    }

    /// Bytes arrived at `now` (a drain waits for the line to go quiet).
    pub fn on_input(&mut self, now: Instant) {
        if let Step::StartDrain(d) = &mut self.step {
            d.last_input = Some(now);
        }
        if let Some(ex) = self.exchange() {
            ex.on_input(now);
        }
    }

    /// A good reply arrived at `now`.
    pub fn on_reply(&mut self, reply: &Reply, now: Instant, out: &mut Out) -> Option<Outcome> {
        let progress = self.exchange()?.on_reply(reply, now, out);
        self.advance(progress, now)
    }

    /// A deadline passed.
    pub fn on_timeout(&mut self, now: Instant, out: &mut Out) -> Option<Outcome> {
        match self.step {
            Step::StopBackoff { attempt, until } if now >= until => {
                out.tx
                    .push_back(Command::SetContinuous { command: 0 }.to_bytes());
                self.step = Step::StopPause {
                    attempt,
                    until: now + STOP_PAUSE,
                };
                None
            }
            Step::StopPause { attempt, until } if now >= until => {
                self.step = Step::StopConfirm {
                    attempt,
                    ex: Exchange::fenced(Command::SetContinuous { command: 0 }, self.timeout, now),
                };
                None
            }
            Step::StartDrain(d) if now >= d.deadline() => {
                out.flush_decoder = true;
                self.start_try(0, now, out);
                None
            }
            Step::StartBackoff { attempt, until } if now >= until => {
                self.start_try(attempt, now, out);
                None
            }
            _ => {
                let progress = self.exchange()?.on_timeout(now, out);
                self.advance(progress, now)
            }
        }
    }

    fn start_try(&mut self, attempt: u32, now: Instant, out: &mut Out) {
        let cmd = Command::SetContinuous {
            command: self.stream.map_or(0, |c| c.code()),
        };
        self.step = Step::Start {
            attempt,
            ex: Exchange::single(cmd, self.timeout, now, out),
        };
    }

    /// The next step after an exchange's progress.
    fn advance(&mut self, progress: Progress, now: Instant) -> Option<Outcome> {
        let result = match progress {
            Progress::Pending => return None,
            Progress::Done(r) => Ok(r),
            Progress::Failed(e) => Err(e),
        };
        let timeout = self.timeout;
        let fenced = |cmd| Exchange::fenced(cmd, timeout, now);
        match std::mem::replace(&mut self.step, Step::Finished) {
            Step::StopConfirm { attempt, .. } => {
                match result {
                    Ok(Reply::Continuous { command: 0, .. }) => {
                        self.step = Step::Firmware(fenced(Command::FirmwareVersion));
                        return None;
                    }
                    Ok(other) => {
                        self.stop_error = anyhow!("the device did not confirm stopping: {other:?}");
                    }
                    Err(e) => self.stop_error = e,
                }
                if attempt + 1 >= TRIES {
                    let e = std::mem::replace(&mut self.stop_error, anyhow!("failed"));
                    return Some(Outcome::Failed(e.context("stopping continuous mode")));
                }
                self.step = Step::StopBackoff {
                    attempt: attempt + 1,
                    until: now + back_off(attempt + 1),
                };
                None
            }
            Step::Firmware(_) => match result {
                Ok(Reply::FirmwareVersion { version }) => {
                    self.firmware = version;
                    self.step = Step::Serial(fenced(Command::SerialNumber));
                    None
                }
                Ok(other) => Some(Outcome::Failed(anyhow!(
                    "unexpected firmware reply {other:?}"
                ))),
                Err(e) => Some(Outcome::Failed(e)),
            },
            Step::Serial(_) => match result {
                Ok(Reply::SerialNumber { serial }) => {
                    self.serial = serial;
                    self.step = self.gain_step(0, 0, None, now);
                    None
                }
                Ok(other) => Some(Outcome::Failed(anyhow!(
                    "unexpected serial-number reply {other:?}"
                ))),
                Err(e) => Some(Outcome::Failed(e)),
            },
            Step::Gain {
                index,
                reads,
                previous,
                ..
            } => {
                let reads = reads + 1;
                let read = match result {
                    Ok(Reply::EepromRead { value, .. }) => {
                        if !plausible_gain_scale(value) {
                            Err(None)
                        } else if previous == Some(value) {
                            Ok(value)
                        } else {
                            Err(Some(value))
                        }
                    }
                    // Cannot happen: the reply code matched.
                    Ok(_) => Err(previous),
                    Err(e) => {
                        self.gain_failed(index, &format!("{e:#} ({TRIES} tries)"));
                        return self.next_gain(index, now);
                    }
                };
                match read {
                    Ok(value) => {
                        self.gain_read(index, value);
                        self.next_gain(index, now)
                    }
                    Err(previous) if reads >= MAX_GAIN_READS => {
                        self.gain_failed(
                            index,
                            &format!(
                                "{MAX_GAIN_READS} reads and no two consecutive ones agreed on a \
                                 plausible value (last {})",
                                previous.map_or("none".to_string(), |v| v.to_string())
                            ),
                        );
                        self.next_gain(index, now)
                    }
                    Err(previous) => {
                        self.step = self.gain_step(index, reads, previous, now);
                        None
                    }
                }
            }
            Step::Temperature(_) => {
                if let Err(e) = result {
                    warn!("no temperature reading at start-up: {e:#}");
                }
                let outcome = Outcome::Identified {
                    firmware: imu_proto::scale::format_firmware_version(self.firmware),
                    serial: self.serial.to_string(),
                    gains: self.gains,
                };
                self.step = match self.stream {
                    Some(_) => Step::StartDrain(Drain::new(now)),
                    None => Step::Finished,
                };
                Some(outcome)
            }
            Step::Start { attempt, .. } => {
                let cmd = self.stream.map_or(0, |c| c.code());
                match result {
                    Ok(Reply::Continuous { command, .. }) if command == cmd => {
                        return Some(Outcome::Done);
                    }
                    Ok(other) => {
                        self.start_error =
                            anyhow!("the device did not confirm continuous mode: {other:?}");
                    }
                    Err(e) => self.start_error = e,
                }
                // Samples of the stream prove it started when the acknowledgement was lost.
                if self.readings > 0 {
                    return Some(Outcome::Done);
                }
                if attempt + 1 >= TRIES {
                    let e = std::mem::replace(&mut self.start_error, anyhow!("failed"));
                    return Some(Outcome::Failed(e.context("starting continuous mode")));
                }
                self.step = Step::StartBackoff {
                    attempt: attempt + 1,
                    until: now + back_off(attempt + 1),
                };
                None
            }
            other => {
                self.step = other;
                None
            }
        }
    }

    fn gain_step(&self, index: usize, reads: u32, previous: Option<u16>, now: Instant) -> Step {
        Step::Gain {
            index,
            reads,
            previous,
            ex: Exchange::fenced(
                Command::ReadEeprom {
                    address: GAIN_WORDS[index].1,
                },
                self.timeout,
                now,
            ),
        }
    }

    fn gain_slot(&mut self, index: usize) -> (&mut u16, &mut bool, u16) {
        match index {
            0 => (
                &mut self.gains.accel,
                &mut self.gains.fallback.accel,
                self.fallback.accel,
            ),
            1 => (
                &mut self.gains.gyro,
                &mut self.gains.fallback.gyro,
                self.fallback.gyro,
            ),
            _ => (
                &mut self.gains.mag,
                &mut self.gains.fallback.mag,
                self.fallback.mag,
            ),
        }
    }

    fn gain_read(&mut self, index: usize, value: u16) {
        let (slot, flag, _) = self.gain_slot(index);
        *slot = value;
        *flag = false;
        self.report
            .push(format!("{} {value} (device)", GAIN_WORDS[index].0));
    }

    fn gain_failed(&mut self, index: usize, why: &str) {
        let (slot, flag, fallback) = self.gain_slot(index);
        *slot = fallback;
        *flag = true;
        let (name, address) = GAIN_WORDS[index];
        self.report.push(format!(
            "{name} {fallback} (configured FALLBACK: EEPROM word {address} unreadable: {why})"
        ));
    }

    /// After GainScale `index`: the next one, or the one line that says which are in force
    /// and the temperature reading.
    fn next_gain(&mut self, index: usize, now: Instant) -> Option<Outcome> {
        if index + 1 < GAIN_WORDS.len() {
            self.step = self.gain_step(index + 1, 0, None, now);
            return None;
        }
        let report = self.report.join(", ");
        if self.gains.fallback.any() {
            error!("GainScales in force: {report}; corrected samples are flagged FALLBACK_GAINS");
        } else {
            info!("GainScales in force: {report}");
        }
        self.step = Step::Temperature(Exchange::fenced(Command::Temperature, self.timeout, now));
        None
    }
}
