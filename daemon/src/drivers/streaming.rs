//! The driver of a unit that streams from power-up (MIP, Xsens, VectorNav): one
//! [`StreamingDriver`] over a [`Unit`], the part that differs per protocol.
//!
//! What is the same for every such unit lives here once: the start (a start-up state machine,
//! or, passive, listening for the first usable frame until the silence timeout), frames made
//! into readings only while the unit is known to stream, the start-up fed every good frame, a
//! passive unit's first usable frame held back behind the session it sets, the start-up's
//! bytes to send and its deadlines, flushing, and the stop sent only to a configured unit.
//! What differs is the [`Unit`]: its decoder ([`FrameDecoder`]), its start-up
//! ([`StartupMachine`]), its frames as readings, what makes a frame usable when passive, what
//! its start-up's outcome means, and its stop bytes.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use imu_bus::recording::{FrameData, SampleFrame};
use imu_proto::DeviceProtocol;
use imu_proto::decoder::DecoderStats;
use imu_proto::decoder::framed::{FramedDecoder, Framing, PacketEvent};

use super::{DeviceIdentity, Driver, DriverEvent, FrameSlot, Held};
use crate::config::DeviceConfig;
use crate::pipeline::{FrameContent, SessionSpec};

/// A unit's streaming decoder, as the driver uses it.
pub trait FrameDecoder: Default {
    /// A good frame.
    type Frame;
    /// Appends received bytes.
    fn push(&mut self, bytes: &[u8]);
    /// Marks the end of the stream so far.
    fn flush(&mut self);
    /// The counters so far.
    fn stats(&self) -> DecoderStats;
    /// The next event, or `None` when more bytes are needed: the packet decoders' own event
    /// type, so theirs is handed over as it is, with no copy of the frame on the way.
    fn next_frame(&mut self) -> Option<PacketEvent<Self::Frame>>;
    /// A frame's bytes on the wire.
    fn bytes(frame: &Self::Frame) -> &[u8];
}

/// The decoders of length-prefixed packet protocols (MIP, Xsens).
impl<F: Framing> FrameDecoder for FramedDecoder<F> {
    type Frame = F::Packet;

    fn push(&mut self, bytes: &[u8]) {
        FramedDecoder::push(self, bytes);
    }

    fn flush(&mut self) {
        FramedDecoder::flush(self);
    }

    fn stats(&self) -> DecoderStats {
        FramedDecoder::stats(self)
    }

    fn next_frame(&mut self) -> Option<PacketEvent<F::Packet>> {
        self.next_event()
    }

    fn bytes(frame: &F::Packet) -> &[u8] {
        F::bytes(frame)
    }
}

/// A unit's start-up state machine: requests out, answers in, deadlines; time passed in.
pub trait StartupMachine {
    /// A good frame, as its decoder yields it.
    type Frame;
    /// What the start-up concluded.
    type Outcome;
    /// A good frame arrived at `now`.
    fn on_frame(&mut self, frame: &Self::Frame, now: Instant) -> Option<Self::Outcome>;
    /// A deadline passed.
    fn on_timeout(&mut self, now: Instant) -> Option<Self::Outcome>;
    /// When [`StartupMachine::on_timeout`] is next due.
    fn deadline(&self) -> Option<Instant>;
    /// The next bytes to write, if any.
    fn transmit(&mut self) -> Option<Vec<u8>>;
}

/// What a start-up's outcome means for the driver.
pub enum Step {
    /// The unit is configured: its session and identity go to the pipeline; `streaming` when
    /// start-up is done with it (else a [`Step::Done`] follows).
    Configured {
        /// The session set up.
        session: SessionSpec,
        /// What was set up.
        identity: DeviceIdentity,
        /// Start-up is done: frames from now on are samples.
        streaming: bool,
    },
    /// Start-up is done: frames from now on are samples.
    Done,
    /// Start-up failed.
    Failed(anyhow::Error),
}

/// A passive unit's stream, taken from its first usable frame.
pub struct Passive {
    /// The session (not verified).
    pub session: SessionSpec,
    /// What the frame says about the unit, for the metadata (`configuration-verified` is
    /// added).
    pub details: Vec<(String, String)>,
}

/// What differs between streaming units (see the module docs).
pub trait Unit {
    /// The protocol, for the identity.
    const PROTOCOL: DeviceProtocol;
    /// The frame a passive unit waits for, as the failure after the silence timeout names it.
    const PASSIVE_WANTS: &'static str;
    /// The unit's decoder.
    type Decoder: FrameDecoder;
    /// The unit's start-up.
    type Startup: StartupMachine<Frame = <Self::Decoder as FrameDecoder>::Frame>;

    /// The unit `config` describes, before it answered.
    fn new(config: &DeviceConfig) -> Self;
    /// A start-up begun at `now` that waits `timeout` for each reply, or why `config` cannot
    /// start one.
    fn startup(
        config: &DeviceConfig,
        timeout: Duration,
        now: Instant,
    ) -> anyhow::Result<Self::Startup>;
    /// What a frame of a streaming unit carries.
    fn content(&mut self, frame: &<Self::Decoder as FrameDecoder>::Frame) -> FrameContent;
    /// Passive: the stream, if `frame` is usable (its clock then restarted).
    fn learn(&mut self, frame: &<Self::Decoder as FrameDecoder>::Frame) -> Option<Passive>;
    /// What the start-up's `outcome` means (its clock restarted on a new session).
    fn outcome(&mut self, outcome: <Self::Startup as StartupMachine>::Outcome) -> Step;
    /// What leaves a configured unit idle on shutdown.
    fn stop_bytes(&self) -> Option<Vec<u8>>;
    /// The pipeline's session before the unit answered.
    fn initial_session(config: &DeviceConfig) -> SessionSpec;
}

/// A streaming unit as a [`Driver`] (see the module docs).
pub struct StreamingDriver<U: Unit> {
    config: DeviceConfig,
    decoder: U::Decoder,
    /// The protocol's own part.
    pub(super) unit: U,
    /// Readings are made (start-up is done, or a passive unit's stream was taken).
    streaming: bool,
    startup: Option<U::Startup>,
    /// Passive: listening for the first usable frame until this time.
    learning: Option<Instant>,
    events: VecDeque<Held>,
    now: Instant,
}

impl<U: Unit> StreamingDriver<U> {
    /// The driver for the unit `config` describes.
    pub fn new(config: &DeviceConfig) -> Self {
        Self::with_unit(config, U::new(config))
    }

    /// The driver of `unit`.
    pub(crate) fn with_unit(config: &DeviceConfig, unit: U) -> Self {
        Self {
            config: config.clone(),
            decoder: U::Decoder::default(),
            unit,
            streaming: false,
            startup: None,
            learning: None,
            events: VecDeque::new(),
            now: Instant::now(),
        }
    }

    /// The driver of `unit` already streaming (no start-up: the offline path, which
    /// configured its simulated unit directly).
    pub(crate) fn already_streaming(config: &DeviceConfig, unit: U) -> Self {
        let mut d = Self::with_unit(config, unit);
        d.streaming = true;
        d
    }

    fn push(&mut self, ev: DriverEvent) {
        self.events.push_back(Held::Event(ev));
    }

    /// Passive: whether `frame` is usable, which then sets the session.
    fn learn(&mut self, frame: &<U::Decoder as FrameDecoder>::Frame) -> bool {
        let Some(passive) = self.unit.learn(frame) else {
            return false;
        };
        self.learning = None;
        self.streaming = true;
        self.push(DriverEvent::Session(passive.session));
        let not_asked = "not asked (passive)".to_string();
        let mut details = passive.details;
        details.push(("configuration-verified".into(), "false".into()));
        self.push(DriverEvent::Identified(Box::new(DeviceIdentity {
            protocol: U::PROTOCOL.name(),
            model: not_asked.clone(),
            firmware: not_asked.clone(),
            serial: not_asked,
            details,
        })));
        self.push(DriverEvent::Ready);
        true
    }

    fn on_outcome(&mut self, outcome: Option<<U::Startup as StartupMachine>::Outcome>) {
        let Some(outcome) = outcome else {
            return;
        };
        match self.unit.outcome(outcome) {
            Step::Configured {
                session,
                identity,
                streaming,
            } => {
                self.push(DriverEvent::Session(session));
                self.push(DriverEvent::Identified(Box::new(identity)));
                if streaming {
                    self.done();
                }
            }
            Step::Done => self.done(),
            Step::Failed(e) => {
                self.startup = None;
                self.push(DriverEvent::Failed(e));
            }
        }
    }

    fn done(&mut self) {
        self.startup = None;
        self.streaming = true;
        self.push(DriverEvent::Ready);
    }
}

impl<U: Unit> Driver for StreamingDriver<U> {
    fn start(&mut self, now: Instant) {
        self.now = now;
        self.streaming = false;
        self.learning = None;
        self.startup = None;
        if !self.config.configure {
            self.learning = Some(now + Duration::from_secs_f64(self.config.silence_timeout_s));
            return;
        }
        let timeout = Duration::from_secs_f64(self.config.reply_timeout_s);
        match U::startup(&self.config, timeout, now) {
            Ok(s) => self.startup = Some(s),
            Err(e) => self.push(DriverEvent::Failed(e)),
        }
    }

    fn handle_input(&mut self, bytes: &[u8], now: Instant) {
        self.now = now;
        self.decoder.push(bytes);
    }

    fn poll_event(&mut self, slot: &mut FrameSlot) -> Option<DriverEvent> {
        if let Some(held) = self.events.pop_front() {
            return Some(held.hand_over(slot));
        }
        Some(match self.decoder.next_frame()? {
            PacketEvent::Packet {
                packet: frame,
                offset,
            } => {
                // Passive: the first usable frame sets the session, which goes out before it.
                let learned = self.learning.is_some() && self.learn(&frame);
                // The start-up's frames (and the data a unit streams before start-up has it
                // configured) are logged only: no samples before it is done. Written in
                // place: the content is most of a frame's bytes on this path.
                slot.content = if self.streaming {
                    self.unit.content(&frame)
                } else {
                    FrameContent::default()
                };
                if let Some(s) = &mut self.startup {
                    let outcome = s.on_frame(&frame, self.now);
                    // The start-up's events (queued here) go out after the frame that ended it.
                    self.on_outcome(outcome);
                }
                let bytes = U::Decoder::bytes(&frame);
                if learned {
                    // The session (queued by `learn`) goes out before its first sample.
                    let frame = SampleFrame {
                        stream_offset: offset,
                        bytes: FrameData::from_slice(bytes),
                    };
                    self.events
                        .push_back(Held::frame(frame, std::mem::take(&mut slot.content)));
                    return self.events.pop_front().map(|held| held.hand_over(slot));
                }
                slot.set_frame(bytes, offset);
                DriverEvent::Frame
            }
            PacketEvent::Rejected {
                bytes,
                offset,
                reason,
            } => DriverEvent::Rejected {
                bytes,
                offset,
                reason,
            },
        })
    }

    fn poll_transmit(&mut self, out: &mut Vec<u8>) -> bool {
        match self.startup.as_mut().and_then(|s| s.transmit()) {
            Some(bytes) => {
                out.extend_from_slice(&bytes);
                true
            }
            None => false,
        }
    }

    fn poll_timeout(&self) -> Option<Instant> {
        match &self.startup {
            Some(s) => s.deadline(),
            None => self.learning,
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        if self.learning.is_some_and(|t| now >= t) {
            self.learning = None;
            self.push(DriverEvent::Failed(anyhow::anyhow!(
                "no {} heard within {:.1} s (passive: nothing is sent to the unit)",
                U::PASSIVE_WANTS,
                self.config.silence_timeout_s
            )));
        }
        if let Some(s) = &mut self.startup {
            let outcome = s.on_timeout(now);
            self.on_outcome(outcome);
        }
    }

    fn flush(&mut self) {
        self.decoder.flush();
        // No readings until the next start: the unit is not known to stream.
        self.streaming = false;
        self.learning = None;
    }

    fn stop_bytes(&self) -> Option<Vec<u8>> {
        // A passive unit is never sent anything, not even a stop.
        self.config
            .configure
            .then(|| self.unit.stop_bytes())
            .flatten()
    }

    fn stats(&self) -> DecoderStats {
        self.decoder.stats()
    }

    fn initial_session(&self) -> SessionSpec {
        U::initial_session(&self.config)
    }
}
