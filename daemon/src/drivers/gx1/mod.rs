//! The 3DM-GX1 as a driver: its reply decoder, its fenced start-up (`startup.rs`), its data
//! replies as readings (`reading.rs`), polling in polled mode, and its simulated unit for the
//! offline path (`offline.rs`).
//!
//! Passive (`device.configure = false`): nothing is ever sent; the unit is taken to stream in
//! continuous mode already, its replies are samples from the first, the GainScales are the
//! configured fallbacks (flagged so), and the identity says the configuration was not verified.

pub mod offline;
pub mod reading;
pub mod startup;
#[cfg(test)]
mod tests;

use std::collections::VecDeque;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use imu_bus::sample::device_protocol;
use imu_proto::command::Command;
use imu_proto::decoder::{DecodeEvent, DecoderStats, ReplyDecoder};
use imu_proto::reply::Reply;
use imu_proto::scale;
use imu_proto::ticks::TickUnwrapper;
use tracing::info;

pub use startup::plausible_gain_scale;
use startup::{Out, Outcome, Startup};

use super::{DeviceIdentity, Driver, DriverEvent, FrameSlot, fallback_gains};
use crate::config::{AcquisitionMode, DeviceConfig, SampleCommand};
use crate::pipeline::{
    Acquisition, FrameContent, Gains, SessionSpec, TemperatureCadence, TickKind, TickLength,
    Timebase,
};

/// The model name a 3DM-GX1 is recorded as (`imud.device` `model`): the unit does not say it.
pub const MODEL: &str = "3DM-GX1";

/// The protocol command of a configured sample command.
pub fn sample_command(c: SampleCommand) -> Command {
    match c {
        SampleCommand::RawBits => Command::RawSensorBits,
        SampleCommand::StabilizedVectors => Command::StabilizedVectors,
        SampleCommand::InstantaneousVectors => Command::InstantaneousVectors,
    }
}

/// The GX1's 16-bit timer at `tick_period_s`: a coarse clock (one or two ticks a sample).
pub fn timebase(tick_period_s: f64) -> Timebase {
    Timebase {
        tick: TickLength::Seconds(tick_period_s),
        kind: TickKind::Coarse,
    }
}

/// The session of a GX1 with `gains`, as `config` acquires it.
pub fn session(config: &DeviceConfig, gains: Gains) -> SessionSpec {
    SessionSpec {
        gains,
        timebase: timebase(config.tick_period_s),
        acquisition: match config.mode {
            AcquisitionMode::Continuous => Acquisition::Streaming,
            AcquisitionMode::Polled => Acquisition::Polled {
                rate_hz: config.poll_rate_hz,
            },
        },
        status_protocol: device_protocol::GX1,
        // A passive unit is asked nothing; otherwise start-up reads the gains back.
        configuration_verified: config.configure,
    }
}

/// The pipeline's session before a GX1 answered: the configured fallback gains.
pub fn initial_session(config: &DeviceConfig) -> SessionSpec {
    session(config, fallback_gains(config))
}

/// What is wrong with `config` for a 3DM-GX1, if anything: (the dotted key, the message).
pub fn config_problem(config: &DeviceConfig) -> Option<(&'static str, String)> {
    (!config.configure && config.mode == AcquisitionMode::Polled).then(|| {
        (
            "device.mode",
            "\"polled\" asks the unit for every sample: a passive unit (device.configure = \
             false) is only listened to"
                .into(),
        )
    })
}

/// Polls in polled mode: the data command, a temperature every `temp_every`-th poll (both
/// encoded once, so a poll does not allocate).
#[derive(Debug)]
struct Polling {
    period: Duration,
    next: Instant,
    n: u64,
    temp_every: u64,
    data: Vec<u8>,
    temperature: Vec<u8>,
    /// A poll is due: true for the temperature.
    due: Option<bool>,
}

/// A 3DM-GX1 (see the module docs).
pub struct Gx1Driver {
    config: DeviceConfig,
    path: PathBuf,
    decoder: ReplyDecoder,
    unwrapper: TickUnwrapper,
    /// The gains of the session, once it is set (readings are made only then).
    session_gains: Option<Gains>,
    startup: Option<Startup>,
    polling: Option<Polling>,
    out: Out,
    events: VecDeque<DriverEvent>,
    now: Instant,
}

impl Gx1Driver {
    /// The driver for the device `config` describes.
    pub fn new(config: &DeviceConfig) -> Self {
        Self {
            config: config.clone(),
            path: config.path.clone(),
            decoder: ReplyDecoder::new(),
            unwrapper: TickUnwrapper::new(),
            session_gains: None,
            startup: None,
            polling: None,
            out: Out::default(),
            events: VecDeque::new(),
            now: Instant::now(),
        }
    }

    /// A driver whose session is already set with `gains` (no start-up: the offline path,
    /// which configured its simulated unit directly).
    pub fn with_session(config: &DeviceConfig, gains: Gains) -> Self {
        let mut d = Self::new(config);
        d.session_gains = Some(gains);
        d
    }

    /// A passive start: the session and identity at once, nothing sent.
    fn start_passive(&mut self) {
        let gains = fallback_gains(&self.config);
        self.session_gains = Some(gains);
        self.unwrapper = TickUnwrapper::new();
        // Streaming; a polled session only in a replay of one (the configuration check
        // refuses polling a live passive unit).
        let spec = session(&self.config, gains);
        self.events.push_back(DriverEvent::Session(spec));
        info!(
            "device {} (3DM-GX1) passive: nothing is sent; its stream is taken as it is, with \
             the configured GainScales {}/{}/{} (not verified)",
            self.path.display(),
            gains.accel,
            gains.gyro,
            gains.mag
        );
        let not_asked = "not asked (passive)".to_string();
        let mut details = vec![
            (
                "tick-period-s".into(),
                self.config.tick_period_s.to_string(),
            ),
            ("configuration-verified".into(), "false".into()),
        ];
        details.extend(gains.metadata());
        self.events
            .push_back(DriverEvent::Identified(Box::new(DeviceIdentity {
                protocol: imu_proto::DeviceProtocol::Gx1.name(),
                model: MODEL.into(),
                firmware: not_asked.clone(),
                serial: not_asked,
                details,
            })));
        self.events.push_back(DriverEvent::Ready);
    }

    fn stream_command(&self) -> Option<Command> {
        (self.config.mode == AcquisitionMode::Continuous)
            .then(|| sample_command(self.config.command))
    }

    /// Handles what the start-up concluded.
    fn on_outcome(&mut self, outcome: Option<Outcome>) {
        match outcome {
            None => {}
            Some(Outcome::Identified {
                firmware,
                serial,
                gains,
            }) => {
                self.session_gains = Some(gains);
                self.unwrapper = TickUnwrapper::new();
                self.events
                    .push_back(DriverEvent::Session(session(&self.config, gains)));
                info!(
                    "device {} (3DM-GX1) firmware {firmware} serial {serial}",
                    self.path.display(),
                );
                let mut details = vec![
                    (
                        "tick-period-s".into(),
                        self.config.tick_period_s.to_string(),
                    ),
                    ("configuration-verified".into(), "true".into()),
                ];
                details.extend(gains.metadata());
                let identity = DeviceIdentity {
                    protocol: imu_proto::DeviceProtocol::Gx1.name(),
                    model: MODEL.into(),
                    firmware,
                    serial,
                    details,
                };
                self.events
                    .push_back(DriverEvent::Identified(Box::new(identity)));
                if self.stream_command().is_none() {
                    self.finish_startup();
                }
            }
            Some(Outcome::Done) => self.finish_startup(),
            Some(Outcome::Failed(e)) => {
                self.startup = None;
                self.events.push_back(DriverEvent::Failed(e));
            }
        }
    }

    /// Start-up is done: the identity goes out and, in polled mode, polling starts now.
    fn finish_startup(&mut self) {
        self.startup = None;
        if self.config.mode == AcquisitionMode::Polled {
            let temp_every = if self.config.temperature_rate_hz > 0.0 {
                (self.config.poll_rate_hz / self.config.temperature_rate_hz)
                    .round()
                    .max(1.0) as u64
            } else {
                u64::MAX
            };
            self.polling = Some(Polling {
                period: Duration::from_secs_f64(1.0 / self.config.poll_rate_hz),
                next: self.now,
                n: 0,
                temp_every,
                data: sample_command(self.config.command).to_bytes(),
                temperature: Command::Temperature.to_bytes(),
                due: None,
            });
        }
        self.events.push_back(DriverEvent::Ready);
    }

    /// What a good reply carries: a temperature, or (once the session is set) a reading.
    /// Inlined into `poll_event`, so the content is built where it goes, in the caller's slot,
    /// rather than on the stack and copied there.
    #[inline(always)]
    fn content(&mut self, reply: &Reply) -> FrameContent {
        if let Reply::Temperature { raw, .. } = *reply {
            return FrameContent {
                temperature: Some((scale::temp_raw_to_c(raw), TemperatureCadence::Each)),
                ..FrameContent::default()
            };
        }
        let (Some(gains), Some(counts)) = (self.session_gains, reading::counts_of(reply)) else {
            return FrameContent::default();
        };
        let ticks = reply.ticks().unwrap_or(0);
        if let Some(s) = &mut self.startup {
            s.readings += 1;
        }
        FrameContent {
            reading: Some(reading::reading(
                reply,
                counts,
                self.unwrapper.unwrap(ticks),
                gains,
            )),
            ..FrameContent::default()
        }
    }

    fn flush_if_asked(&mut self) {
        if std::mem::take(&mut self.out.flush_decoder) {
            self.decoder.flush();
        }
    }
}

impl Driver for Gx1Driver {
    fn start(&mut self, now: Instant) {
        self.now = now;
        self.session_gains = None;
        self.polling = None;
        self.out = Out::default();
        if !self.config.configure {
            self.start_passive();
            return;
        }
        self.startup = Some(Startup::new(
            fallback_gains(&self.config),
            Duration::from_secs_f64(self.config.reply_timeout_s),
            self.stream_command(),
            now,
        ));
    }

    fn handle_input(&mut self, bytes: &[u8], now: Instant) {
        self.now = now;
        if let Some(s) = &mut self.startup {
            if s.discarding() {
                return;
            }
            s.on_input(now);
        }
        self.decoder.push(bytes);
    }

    fn poll_event(&mut self, slot: &mut FrameSlot) -> Option<DriverEvent> {
        // Start-up's events (no frames among them) go before the frames decoded after it.
        if let Some(ev) = self.events.pop_front() {
            return Some(ev);
        }
        let ev = match self.decoder.next_event()? {
            DecodeEvent::Frame {
                reply,
                bytes,
                offset,
            } => {
                // Written in place: the content is most of a frame's bytes on this path.
                slot.content = self.content(&reply);
                if let Some(s) = &mut self.startup {
                    let outcome = s.on_reply(&reply, self.now, &mut self.out);
                    self.on_outcome(outcome);
                    self.flush_if_asked();
                }
                slot.set_frame(&bytes, offset);
                DriverEvent::Frame
            }
            DecodeEvent::Rejected {
                bytes,
                offset,
                reason,
            } => DriverEvent::Rejected {
                bytes,
                offset,
                reason,
            },
        };
        Some(ev)
    }

    fn poll_transmit(&mut self, out: &mut Vec<u8>) -> bool {
        if let Some(bytes) = self.out.tx.pop_front() {
            out.extend_from_slice(&bytes);
            return true;
        }
        let Some(p) = &mut self.polling else {
            return false;
        };
        match p.due.take() {
            Some(true) => out.extend_from_slice(&p.temperature),
            Some(false) => out.extend_from_slice(&p.data),
            None => return false,
        }
        true
    }

    fn poll_timeout(&self) -> Option<Instant> {
        match (&self.startup, &self.polling) {
            (Some(s), _) => s.deadline(),
            (None, Some(p)) => Some(p.next),
            (None, None) => None,
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        if let Some(s) = &mut self.startup {
            let outcome = s.on_timeout(now, &mut self.out);
            self.on_outcome(outcome);
            self.flush_if_asked();
            return;
        }
        if let Some(p) = &mut self.polling
            && now >= p.next
        {
            p.n += 1;
            p.due = Some(p.n.is_multiple_of(p.temp_every));
            // Missed polls are skipped, not made up.
            while p.next <= now {
                p.next += p.period;
            }
        }
    }

    fn flush(&mut self) {
        self.decoder.flush();
        // No readings until the next start sets the gains again.
        self.session_gains = None;
        self.polling = None;
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        // A passive unit is never sent anything, not even a stop.
        (self.config.configure && self.config.mode == AcquisitionMode::Continuous)
            .then(|| Command::SetContinuous { command: 0 }.to_bytes())
    }

    fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    fn initial_session(&self) -> SessionSpec {
        initial_session(&self.config)
    }
}
