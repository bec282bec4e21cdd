//! Which protocol the device on the port speaks, when the configuration does not say: a state
//! machine like the drivers', time passed in.
//!
//! 1. Listen: a unit that streams already says who it is. Several good frames of one protocol
//!    and fewer of each other decide (a MIP stream holds, by chance, a GX1-shaped run with a
//!    good 16-bit checksum about once in 65536 candidates, so one frame is not proof). An
//!    Xsens MTi powers up streaming, so it is usually recognised here.
//! 2. Ask the 3DM-GX1 question, its firmware query (one byte, 0xF0, which a MIP unit discards
//!    as garbage): a GX1 answers with an 0xF0 reply. No data reply is provoked, so nothing
//!    but the configured stream ever becomes a sample.
//! 3. Ask the MIP question, "set to idle": only a MIP unit acknowledges it (and it stops one
//!    that streams).
//! 4. Ask the Xsens question, `GoToConfig`: only an MTi acknowledges it (and it stops its
//!    stream).
//! 5. Ask the VectorNav question, a read of its model register (`$VNRRG,01`): only a
//!    VectorNav unit answers it. (A VectorNav unit usually streams its power-up `$VNYPR`
//!    output and is recognised in step 1.)
//!
//! Passive (`device.configure = false`), only step 1: the probe listens for up to the silence
//! time-out (at least [`LISTEN`]) and asks nothing, so a unit that streams is recognised without
//! a command.
//!
//! No answer is an error: the session is retried with back-off like any failed start-up. The
//! bytes heard go, as frames only, to the driver of the protocol found, so they are logged
//! like any other bytes from the device; the probe's own decoders keep them out of the
//! status's fault counters.

use std::time::{Duration, Instant};

use anyhow::anyhow;
use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_proto::mip::{MipCommand, MipDecoder, MipEvent, MipReply};
use imu_proto::vectornav::{Check, Register, VnCommand, VnDecoder, VnEvent, VnReply, reg};
use imu_proto::xsens::{XsensCommand, XsensDecoder, XsensEvent, mid};
use tracing::info;

use crate::config::DeviceConfig;

/// How long to listen before asking.
pub const LISTEN: Duration = Duration::from_millis(300);
/// Good frames of one protocol that identify a streaming unit.
const STREAM_EVIDENCE: u32 = 3;

/// Where the probe is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// Listening for a stream until the deadline.
    Listen,
    /// The GX1 firmware query is out.
    AskGx1,
    /// The MIP "set to idle" is out.
    AskMip,
    /// The Xsens `GoToConfig` is out.
    AskXsens,
    /// The VectorNav model read is out.
    AskVectornav,
    /// Decided (or failed): the result is waiting to be taken.
    Done,
}

/// The probe of one session.
pub struct Probe {
    stage: Stage,
    deadline: Instant,
    started: Instant,
    now: Instant,
    reply_timeout: Duration,
    /// Only listen: never ask.
    passive: bool,
    bytes: Vec<u8>,
    gx1: ReplyDecoder,
    mip: MipDecoder,
    xsens: XsensDecoder,
    gx1_frames: u32,
    mip_packets: u32,
    xsens_messages: u32,
    gx1_firmware_reply: bool,
    mip_idle_ack: bool,
    xsens_config_ack: bool,
    vectornav: VnDecoder,
    vectornav_frames: u32,
    vectornav_model_reply: bool,
    transmit: Option<Vec<u8>>,
    result: Option<anyhow::Result<(DeviceProtocol, Vec<u8>)>>,
}

impl Probe {
    /// A probe that starts listening at `now`.
    pub fn new(config: &DeviceConfig, now: Instant) -> Self {
        let passive = !config.configure;
        let listen = if passive {
            LISTEN.max(Duration::from_secs_f64(config.silence_timeout_s))
        } else {
            LISTEN
        };
        Self {
            stage: Stage::Listen,
            deadline: now + listen,
            started: now,
            now,
            reply_timeout: Duration::from_secs_f64(config.reply_timeout_s),
            passive,
            bytes: Vec::new(),
            gx1: ReplyDecoder::default(),
            mip: MipDecoder::default(),
            xsens: XsensDecoder::default(),
            gx1_frames: 0,
            mip_packets: 0,
            xsens_messages: 0,
            gx1_firmware_reply: false,
            mip_idle_ack: false,
            xsens_config_ack: false,
            vectornav: VnDecoder::default(),
            vectornav_frames: 0,
            vectornav_model_reply: false,
            transmit: None,
            result: None,
        }
    }

    /// The time of the last input or timeout.
    pub fn now(&self) -> Instant {
        self.now
    }

    /// Bytes from the port.
    pub fn handle_input(&mut self, bytes: &[u8], now: Instant) {
        self.now = now;
        if self.stage == Stage::Done {
            return;
        }
        self.bytes.extend_from_slice(bytes);
        self.gx1.push(bytes);
        self.mip.push(bytes);
        self.xsens.push(bytes);
        self.vectornav.push(bytes);
        while let Some(ev) = self.gx1.next_event() {
            if let DecodeEvent::Frame { reply, .. } = ev {
                self.gx1_frames += 1;
                self.gx1_firmware_reply |= reply.code() == Command::FirmwareVersion.code();
            }
        }
        let idle = MipCommand::SetToIdle.descriptor();
        while let Some(ev) = self.mip.next_event() {
            if let MipEvent::Packet { packet, .. } = ev {
                self.mip_packets += 1;
                self.mip_idle_ack |= MipReply::decode_packet(&packet)
                    .is_ok_and(|r| r.iter().any(|r| (r.descriptor_set, r.command) == idle));
            }
        }
        while let Some(ev) = self.xsens.next_event() {
            if let XsensEvent::Packet { packet, .. } = ev {
                self.xsens_messages += 1;
                self.xsens_config_ack |= packet.mid() == mid::GO_TO_CONFIG_ACK;
            }
        }
        while let Some(ev) = self.vectornav.next_event() {
            match ev {
                VnEvent::Binary { .. } => self.vectornav_frames += 1,
                VnEvent::Ascii { sentence, .. } => {
                    self.vectornav_frames += 1;
                    self.vectornav_model_reply |= matches!(
                        VnReply::decode(&sentence),
                        Ok(VnReply::Read(Register::Model(_)))
                    );
                }
                VnEvent::Rejected { .. } => {}
            }
        }
        match self.stage {
            Stage::Listen => {
                if let Some(p) = self.streaming() {
                    self.decide(p, "it streams");
                }
            }
            Stage::AskGx1 if self.gx1_firmware_reply => {
                self.decide(DeviceProtocol::Gx1, "it answers the 3DM-GX1 firmware query");
            }
            Stage::AskMip if self.mip_idle_ack => {
                self.decide(DeviceProtocol::Mip, "it acknowledges a MIP \"set to idle\"");
            }
            Stage::AskXsens if self.xsens_config_ack => {
                self.decide(DeviceProtocol::Xsens, "it acknowledges an Xsens GoToConfig");
            }
            Stage::AskVectornav if self.vectornav_model_reply => {
                self.decide(
                    DeviceProtocol::Vectornav,
                    "it answers a VectorNav model register read",
                );
            }
            _ => {}
        }
    }

    /// The protocol of a unit that streams, if the evidence says it.
    fn streaming(&self) -> Option<DeviceProtocol> {
        let counts = [
            (DeviceProtocol::Gx1, self.gx1_frames),
            (DeviceProtocol::Mip, self.mip_packets),
            (DeviceProtocol::Xsens, self.xsens_messages),
            (DeviceProtocol::Vectornav, self.vectornav_frames),
        ];
        // The protocol with the most good frames, if it has enough and strictly more than
        // every other.
        counts.iter().find_map(|&(p, n)| {
            (n >= STREAM_EVIDENCE && counts.iter().all(|&(q, m)| q == p || n > m)).then_some(p)
        })
    }

    fn decide(&mut self, protocol: DeviceProtocol, why: &str) {
        info!("protocol {protocol} (probed: {why})");
        self.stage = Stage::Done;
        self.result = Some(Ok((protocol, std::mem::take(&mut self.bytes))));
    }

    /// Bytes to write (a question), appended to `out`.
    pub fn poll_transmit(&mut self, out: &mut Vec<u8>) -> bool {
        match self.transmit.take() {
            Some(bytes) => {
                out.extend_from_slice(&bytes);
                true
            }
            None => false,
        }
    }

    /// When the current stage gives up waiting.
    pub fn poll_timeout(&self) -> Option<Instant> {
        (self.stage != Stage::Done).then_some(self.deadline)
    }

    /// Time passed: the next question, or the end.
    pub fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        if now < self.deadline {
            return;
        }
        match self.stage {
            Stage::Listen if self.passive => {
                self.stage = Stage::Done;
                self.result = Some(Err(anyhow!(
                    "no stream of a known protocol heard within {:.1} s (passive: nothing is \
                     asked; set device.protocol, or check that the unit streams)",
                    (self.deadline - self.started).as_secs_f64()
                )));
            }
            Stage::Listen => {
                self.stage = Stage::AskGx1;
                self.transmit = Some(Command::FirmwareVersion.to_bytes());
                self.deadline = now + self.reply_timeout;
            }
            Stage::AskGx1 => {
                self.stage = Stage::AskMip;
                self.transmit = Some(MipCommand::SetToIdle.to_packet().as_bytes().to_vec());
                self.deadline = now + self.reply_timeout;
            }
            Stage::AskMip => {
                self.stage = Stage::AskXsens;
                self.transmit = Some(XsensCommand::GoToConfig.to_message().as_bytes().to_vec());
                self.deadline = now + self.reply_timeout;
            }
            Stage::AskXsens => {
                self.stage = Stage::AskVectornav;
                self.transmit = Some(
                    VnCommand::Read(reg::MODEL)
                        .to_sentence(Check::Checksum8)
                        .as_bytes()
                        .to_vec(),
                );
                self.deadline = now + self.reply_timeout;
            }
            Stage::AskVectornav => {
                self.stage = Stage::Done;
                self.result = Some(Err(anyhow!(
                    "the device answers neither the 3DM-GX1 firmware query, a MIP \
                     \"set to idle\", an Xsens GoToConfig nor a VectorNav model read (set \
                     device.protocol to skip \
                     this probe)"
                )));
            }
            Stage::Done => {}
        }
    }

    /// The protocol found and the bytes heard, or why none was, once decided.
    pub fn poll_result(&mut self) -> Option<anyhow::Result<(DeviceProtocol, Vec<u8>)>> {
        self.result.take()
    }
}
