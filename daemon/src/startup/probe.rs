//! Which protocol the device on the port speaks, when the configuration does not say.
//!
//! 1. Listen: a unit that streams already says who it is. Several good frames of one protocol
//!    and fewer of the other decide (a MIP stream holds, by chance, a GX1-shaped run with a
//!    good 16-bit checksum about once in 65536 candidates, so one frame is not proof).
//! 2. Ask the 3DM-GX1 question, its firmware query (one byte, 0xF0, which a MIP unit discards
//!    as garbage): a GX1 answers with an 0xF0 reply. No data reply is provoked, so nothing
//!    but the configured stream ever becomes a sample.
//! 3. Ask the MIP question, "set to idle": only a MIP unit acknowledges it (and it stops one
//!    that streams).
//!
//! No answer is an error: the session is retried with back-off like any failed start-up. The
//! bytes heard go, as frames only, to the decoder of the protocol found, so they are logged
//! like any other bytes from the device; the probe's own decoders keep them out of the
//! status's fault counters.

use std::time::Duration;

use anyhow::{Context, bail};
use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::decoder::{DecodeEvent, ReplyDecoder};
use imu_proto::mip::{MipCommand, MipDecoder, MipEvent, MipReply};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_serial::SerialStream;
use tracing::info;

use crate::session::{Daemon, now_ns};

/// How long to listen before asking, s.
const LISTEN: Duration = Duration::from_millis(300);
/// Good frames of one protocol that identify a streaming unit.
const STREAM_EVIDENCE: u32 = 3;

/// What the probe's decoders made of the bytes heard.
#[derive(Default)]
struct Heard {
    bytes: Vec<u8>,
    gx1: ReplyDecoder,
    mip: MipDecoder,
    gx1_frames: u32,
    mip_packets: u32,
    gx1_firmware_reply: bool,
    mip_idle_ack: bool,
}

impl Heard {
    fn push(&mut self, bytes: &[u8]) {
        self.bytes.extend_from_slice(bytes);
        self.gx1.push(bytes);
        self.mip.push(bytes);
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
    }

    /// The protocol of a unit that streams, if the evidence says it.
    fn streaming(&self) -> Option<DeviceProtocol> {
        if self.mip_packets >= STREAM_EVIDENCE && self.mip_packets > self.gx1_frames {
            Some(DeviceProtocol::Mip)
        } else if self.gx1_frames >= STREAM_EVIDENCE && self.gx1_frames > self.mip_packets {
            Some(DeviceProtocol::Gx1)
        } else {
            None
        }
    }
}

impl Daemon {
    /// Reads into `heard` for `span` or until `done` says so.
    async fn listen(
        &mut self,
        port: &mut SerialStream,
        heard: &mut Heard,
        span: Duration,
        done: impl Fn(&Heard) -> bool,
    ) -> anyhow::Result<()> {
        let deadline = tokio::time::Instant::now() + span;
        let mut buf = [0u8; 512];
        while !done(heard) {
            let Ok(read) = tokio::time::timeout_at(deadline, port.read(&mut buf)).await else {
                return Ok(());
            };
            let n = read.context("reading from the device")?;
            if n == 0 {
                bail!("the device closed the line");
            }
            heard.push(&buf[..n]);
        }
        Ok(())
    }

    /// Which protocol the device on `port` speaks (see the module docs).
    pub(super) async fn probe(
        &mut self,
        port: &mut SerialStream,
    ) -> anyhow::Result<DeviceProtocol> {
        let timeout = Duration::from_secs_f64(self.config.device.reply_timeout_s);
        let mut heard = Heard::default();
        self.listen(port, &mut heard, LISTEN, |h| h.streaming().is_some())
            .await?;
        let found = match heard.streaming() {
            Some(p) => (p, "it streams"),
            None => {
                port.write_all(&Command::FirmwareVersion.to_bytes())
                    .await
                    .context("writing to the device")?;
                self.listen(port, &mut heard, timeout, |h| h.gx1_firmware_reply)
                    .await?;
                if heard.gx1_firmware_reply {
                    (DeviceProtocol::Gx1, "it answers the 3DM-GX1 firmware query")
                } else {
                    port.write_all(MipCommand::SetToIdle.to_packet().as_bytes())
                        .await
                        .context("writing to the device")?;
                    self.listen(port, &mut heard, timeout, |h| h.mip_idle_ack)
                        .await?;
                    if !heard.mip_idle_ack {
                        bail!(
                            "the device answers neither the 3DM-GX1 firmware query nor a MIP \
                             \"set to idle\" (set device.protocol to skip this probe)"
                        );
                    }
                    (DeviceProtocol::Mip, "it acknowledges a MIP \"set to idle\"")
                }
            }
        };
        let (protocol, why) = found;
        info!("protocol {protocol} (probed: {why})");
        self.link.set_protocol(protocol);
        self.link.push(&heard.bytes);
        let (mono, wall) = now_ns();
        self.link
            .log_into(&mut self.pipeline, mono, wall, &self.sinks);
        Ok(protocol)
    }
}
