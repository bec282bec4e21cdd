//! `imud replay FILE`: a byte capture through the same driver and pipeline as a live unit, with
//! the same outputs (MCAP, shared memory, ROS 2, health).
//!
//! Three kinds of capture: an imud recording (its `/imu/raw_frame` records, every byte the
//! device sent, each with the host times of the read that completed it), a raw byte capture
//! (a vendor tool's `.bin`), or a hex dump of one. A recording's frames are handed over with
//! their recorded host times, so the clock fit, the stamps and everything after them are what
//! the live run computed: a single-session recording replayed without a new calibration
//! reproduces its `/imu/data` bit for bit. Its device is taken as it was recorded (protocol,
//! GainScales, tick period, acquisition from the recording's metadata) and run passive, so no
//! start-up is replayed. A raw capture has no times: its bytes arrive at the line's pace
//! (`device.baud`, 10 bits a byte) from the moment the replay starts.
//!
//! A recording that spans a reconnect is replayed as the live run had it, one device session
//! after another: the daemon records a status with the device disconnected as soon as a session
//! is lost (its first status while it waits to retry), so a status that says disconnected after
//! one that said connected marks the end of a session, and the frames read after it are the
//! next session's. At that boundary the replay does what the daemon did: the decoder's partial
//! frame is ended and a reconnect is counted; the driver starts again (a new session: the tick
//! unwrapping, the clock fit, the gap accounting and the rate start afresh) where the live
//! session began to stream. A recording says where that was: the first frame a sample was made
//! of (the recorder writes that frame's `/imu/raw_frame` record and then its `/imu/raw` one,
//! with at most the temperature taken from it between them);
//! the frames before it, a start-up's replies and data a unit still streaming sent before the
//! start-up stopped it, were logged only and are replayed so. A session lost during its
//! start-up (never connected) leaves no boundary; it made no samples, so the next session's
//! samples come out the same.
//!
//! `--speed 1` keeps the recorded pace, `--speed 10` ten times faster, `max` as fast as the CPU
//! allows; the stamps are the recorded ones whatever the speed.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, anyhow, bail};
use imu_bus::recording::{RecordedMessage, for_each_record};

use crate::config::Config;
use crate::drivers::Driver;
use crate::session::{Daemon, now_ns};

/// How fast a capture is replayed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Speed {
    /// This many times the recorded pace.
    Times(f64),
    /// As fast as the CPU allows.
    Max,
}

impl std::str::FromStr for Speed {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "max" {
            return Ok(Speed::Max);
        }
        match s.parse::<f64>() {
            Ok(x) if x.is_finite() && x > 0.0 => Ok(Speed::Times(x)),
            _ => Err(format!(
                "{s:?} is no speed: a positive factor of the recorded pace (1, 10) or \"max\""
            )),
        }
    }
}

/// What a capture file is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureKind {
    /// An imud recording: its `/imu/raw_frame` records.
    Recording,
    /// Raw bytes as the device sent them.
    Raw,
    /// A hex dump of them.
    Hex,
}

/// Bytes as they arrived: one read of the port.
#[derive(Debug, Clone, PartialEq)]
pub struct Chunk {
    /// The bytes.
    pub bytes: Vec<u8>,
    /// Host monotonic time of the read, ns.
    pub mono_ns: u64,
    /// Host wall time of the read, ns.
    pub wall_ns: u64,
    /// A recording's frame that the live run made a sample of (its `/imu/raw` record follows
    /// it in the file); false for a raw capture's bytes.
    pub sampled: bool,
}

/// A capture read into memory.
#[derive(Debug, Clone)]
pub struct Capture {
    /// The file.
    pub path: PathBuf,
    /// What it is.
    pub kind: CaptureKind,
    /// The reads, in order.
    pub chunks: Vec<Chunk>,
    /// A recording's metadata (empty for raw captures).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Indices into `chunks` where a new device session began (a reconnect in the live run),
    /// in order; empty for a single session and for raw captures.
    pub session_starts: Vec<usize>,
}

/// Bytes of a raw capture handed over at once.
const RAW_CHUNK: usize = 64;

impl Capture {
    /// Reads `path`: an imud recording (MCAP), a hex dump (`.hex`, `.txt`) or raw bytes. A
    /// raw capture's bytes are paced at `baud` from `start` (mono, wall ns).
    pub fn read(path: &Path, baud: u32, start: (u64, u64)) -> anyhow::Result<Self> {
        if imu_bus::mcap_read::has_mcap_magic(path)
            .with_context(|| format!("reading {}", path.display()))?
        {
            return Self::read_recording(path);
        }
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        let hex = matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("hex" | "txt")
        );
        let (kind, data) = if hex {
            let text = String::from_utf8(bytes)
                .map_err(|_| anyhow!("{}: a hex dump must be text", path.display()))?;
            (CaptureKind::Hex, parse_hex(&text, path)?)
        } else {
            (CaptureKind::Raw, bytes)
        };
        let ns_per_byte = 10.0e9 / f64::from(baud.max(1));
        let chunks = data
            .chunks(RAW_CHUNK)
            .enumerate()
            .map(|(i, c)| {
                // The read completes with its last byte.
                let t = ((i * RAW_CHUNK + c.len()) as f64 * ns_per_byte) as u64;
                Chunk {
                    bytes: c.to_vec(),
                    mono_ns: start.0 + t,
                    wall_ns: start.1 + t,
                    sampled: false,
                }
            })
            .collect();
        Ok(Self {
            path: path.to_path_buf(),
            kind,
            chunks,
            metadata: BTreeMap::new(),
            session_starts: Vec::new(),
        })
    }

    fn read_recording(path: &Path) -> anyhow::Result<Self> {
        let mut chunks = Vec::new();
        // (host monotonic time, device connected) of every status, in recorded order.
        let mut statuses = Vec::new();
        // The recorder writes a sample's frame and then its raw sample, one after the other, or
        // with the temperature taken from that frame between them (a MIP unit's, recorded once
        // a second).
        let mut after_frame = false;
        let report = for_each_record(path, |m| {
            let frame = match m {
                RecordedMessage::Frame(_) => true,
                RecordedMessage::Temperature(_) => after_frame,
                _ => false,
            };
            match m {
                RecordedMessage::Frame(f) => chunks.push(Chunk {
                    bytes: f.bytes,
                    mono_ns: f.t_host_monotonic_ns,
                    wall_ns: f.t_host_wall_ns,
                    sampled: false,
                }),
                RecordedMessage::Raw(_) if after_frame => {
                    if let Some(c) = chunks.last_mut() {
                        c.sampled = true;
                    }
                }
                RecordedMessage::Status { status, .. } => {
                    statuses.push((status.t_host_monotonic_ns, status.device_connected != 0))
                }
                _ => {}
            }
            after_frame = frame;
        })
        .with_context(|| format!("reading the recording {}", path.display()))?;
        let session_starts = session_starts(&chunks, &statuses);
        if chunks.is_empty() {
            bail!(
                "{}: the recording holds no /imu/raw_frame records",
                path.display()
            );
        }
        Ok(Self {
            path: path.to_path_buf(),
            kind: CaptureKind::Recording,
            chunks,
            metadata: report.metadata,
            session_starts,
        })
    }

    /// The configuration to replay with: a recording's own (`imud.config`) with its device as
    /// recorded (protocol, GainScales, tick period), else `base`; passive either way.
    pub fn config(&self, base: &Config) -> anyhow::Result<Config> {
        let mut config = match self.metadata.get("imud.config").and_then(|m| m.get("toml")) {
            Some(text) => {
                Config::from_toml_str(text, &format!("{} (imud.config)", self.path.display()))?
            }
            None => base.clone(),
        };
        if let Some(device) = self.metadata.get("imud.device") {
            // A ROS 2 input's recording names no serial protocol: its configuration's
            // `input.ros2-topic` makes the same driver.
            if let Some(p) = device.get("protocol")
                && config.input.ros2_topic.is_none()
            {
                config.device.protocol = Some(p.parse().map_err(|e| {
                    anyhow!("{}: imud.device protocol {p:?}: {e}", self.path.display())
                })?);
            }
            let word = |key: &str| device.get(key).and_then(|v| v.parse::<u16>().ok());
            if let (Some(a), Some(g), Some(m)) = (
                word("gain-scale-accel"),
                word("gain-scale-gyro"),
                word("gain-scale-mag"),
            ) {
                config.device.fallback_gains.accel = a;
                config.device.fallback_gains.gyro = g;
                config.device.fallback_gains.mag = m;
            }
            if let Some(t) = device.get("tick-period-s").and_then(|v| v.parse().ok()) {
                config.device.tick_period_s = t;
            }
        }
        config.device.configure = false;
        Ok(config)
    }
}

/// Where the live run's device sessions began, as indices into `chunks`: the first chunk read
/// after each status that says the device is disconnected following one that said it was
/// connected (see the module docs). `statuses` are (host monotonic ns, connected) in recorded
/// order; both lists carry the daemon's own CLOCK_MONOTONIC times.
pub fn session_starts(chunks: &[Chunk], statuses: &[(u64, bool)]) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut connected = false;
    for &(t_ns, now_connected) in statuses {
        if connected && !now_connected {
            let i = chunks.partition_point(|c| c.mono_ns <= t_ns);
            if i > 0 && i < chunks.len() && starts.last() != Some(&i) {
                starts.push(i);
            }
        }
        connected = now_connected;
    }
    starts
}

/// Hex bytes from `text`: pairs of hex digits, separated by white space or not; `#` starts a
/// comment; a line may start with an offset ending in `:` (as `xxd -p` or `od` write them).
pub fn parse_hex(text: &str, path: &Path) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        let line = match line.split_once(':') {
            Some((offset, rest)) if offset.trim().chars().all(|c| c.is_ascii_hexdigit()) => rest,
            _ => line,
        };
        let digits: Vec<char> = line.chars().filter(|c| !c.is_whitespace()).collect();
        if let Some(bad) = digits.iter().find(|c| !c.is_ascii_hexdigit()) {
            bail!(
                "{}:{}: {bad:?} is not a hex digit (a hex dump holds byte pairs, `#` comments \
                 and optional `offset:` prefixes)",
                path.display(),
                i + 1
            );
        }
        if !digits.len().is_multiple_of(2) {
            bail!(
                "{}:{}: an odd number of hex digits (a byte is two)",
                path.display(),
                i + 1
            );
        }
        for pair in digits.chunks(2) {
            let s: String = pair.iter().collect();
            out.push(u8::from_str_radix(&s, 16).expect("two hex digits"));
        }
    }
    Ok(out)
}

/// What a replay did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReplayReport {
    /// Reads handed to the driver.
    pub chunks: u64,
    /// Samples made.
    pub samples: u64,
}

impl Daemon {
    /// Replays `capture` through the device's driver and the pipeline (see the module docs).
    pub fn replay(&mut self, capture: &Capture, speed: Speed) -> anyhow::Result<ReplayReport> {
        let Some(first) = capture.chunks.first() else {
            bail!("{}: nothing to replay", capture.path.display());
        };
        let t0 = first.mono_ns;
        let origin = Instant::now();
        // A recording's session starts, as the live one streamed, at its first frame that made
        // a sample: the frames before it (a start-up's, and data a unit still streaming sent
        // before start-up stopped it) were logged only, and so they are here. A capture without
        // that knowledge starts at once.
        let start_at_samples = capture.chunks.iter().any(|c| c.sampled);
        let mut started = !start_at_samples;
        if started {
            self.device.start(origin);
        }
        let status_every_ns = (self.config.publish.status_interval_s * 1e9) as u64;
        let mut next_status = t0 + status_every_ns;
        let mut report = ReplayReport {
            chunks: 0,
            samples: 0,
        };
        let mut ready = false;
        let (mut mono, mut wall) = (first.mono_ns, first.wall_ns);
        let mut session_starts = capture.session_starts.iter().peekable();
        for (i, c) in capture.chunks.iter().enumerate() {
            // Recorded times never go back; a capture that does is taken as it is.
            let since = Duration::from_nanos(c.mono_ns.saturating_sub(t0));
            if let Speed::Times(x) = speed {
                let due = origin + since.div_f64(x);
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                }
            }
            let now = origin + since;
            while let Some(t) = self.device.poll_timeout().filter(|t| *t <= now) {
                self.device.handle_timeout(t);
                ready |= self.end_of_start(mono, wall)?;
            }
            if session_starts.next_if_eq(&&i).is_some() {
                // The live run lost the device here and reconnected: the session ends, as the
                // daemon's reconnect loop ended it, and the next starts as the first did.
                self.device.flush();
                ready |= self.end_of_start(mono, wall)?;
                self.publish_status_at(false, mono, wall);
                self.reconnects += 1;
                started = !start_at_samples;
                if started {
                    self.device.start(now);
                }
            }
            if !started && c.sampled {
                self.device.start(now);
                started = true;
            }
            (mono, wall) = (c.mono_ns, c.wall_ns);
            self.device.handle_input(&c.bytes, now);
            ready |= self.end_of_start(mono, wall)?;
            report.chunks += 1;
            if mono >= next_status {
                self.publish_status_at(ready, mono, wall);
                next_status = mono + status_every_ns;
            }
        }
        self.device.flush();
        self.end_of_start(mono, wall)?;
        self.publish_status_at(false, mono, wall);
        report.samples = self.pipeline.counters().samples;
        if !ready {
            bail!(
                "{}: no stream of the device was recognised in the capture",
                capture.path.display()
            );
        }
        Ok(report)
    }

    /// Hands the driver's events over; true once start-up is done, an error if it failed.
    fn end_of_start(&mut self, mono: u64, wall: u64) -> anyhow::Result<bool> {
        match self.take_events_at(mono, wall) {
            Some(Ok(())) => Ok(true),
            Some(Err(e)) => Err(e),
            None => Ok(false),
        }
    }
}

/// The host clocks now, for a raw capture's first byte.
pub fn start_times() -> (u64, u64) {
    now_ns()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_dumps_read_with_offsets_comments_and_any_spacing() {
        let text = "# a capture\n00000000: 75 65 01\n0003:0c04 # more\n\nff\n";
        let bytes = parse_hex(text, Path::new("c.hex")).unwrap();
        assert_eq!(bytes, [0x75, 0x65, 0x01, 0x0c, 0x04, 0xff]);
    }

    #[test]
    fn a_bad_hex_dump_names_file_and_line() {
        let e = parse_hex("75 65\n75 6g\n", Path::new("c.hex")).unwrap_err();
        assert!(e.to_string().starts_with("c.hex:2: 'g'"), "{e}");
        let e = parse_hex("756\n", Path::new("c.hex")).unwrap_err();
        assert!(e.to_string().contains("c.hex:1: an odd number"), "{e}");
    }

    #[test]
    fn a_status_saying_disconnected_after_connected_starts_the_next_session() {
        let chunk = |mono_ns| Chunk {
            bytes: vec![0x75],
            mono_ns,
            wall_ns: mono_ns,
            sampled: false,
        };
        let chunks: Vec<Chunk> = [5, 15, 30, 55, 65, 80, 95, 120]
            .into_iter()
            .map(chunk)
            .collect();
        let statuses = [
            // Start-up of the first session: not yet connected, no boundary.
            (10, false),
            (20, true),
            (50, true),
            // Lost after the chunk at 55: the next read (65) begins the second session.
            (60, false),
            (70, false),
            (90, true),
            // Lost again, and the last one at shutdown with nothing read after it.
            (100, false),
            (130, true),
            (140, false),
        ];
        assert_eq!(session_starts(&chunks, &statuses), vec![4, 7]);
        assert!(session_starts(&chunks, &[(10, true), (20, true)]).is_empty());
    }

    #[test]
    fn speeds_are_factors_or_max() {
        assert_eq!("max".parse::<Speed>(), Ok(Speed::Max));
        assert_eq!("10".parse::<Speed>(), Ok(Speed::Times(10.0)));
        assert!("0".parse::<Speed>().is_err());
        assert!("fast".parse::<Speed>().is_err());
    }
}
