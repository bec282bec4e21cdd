//! The 3DM-GX1's start-up sequence, built so that no reply can be taken for another request's.
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

use std::time::Duration;

use anyhow::{Context, anyhow, bail};
use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::decoder::DecodeEvent;
use imu_proto::device::{ACCEL_GAIN_SCALE_ADDR, GYRO_GAIN_SCALE_ADDR, MAG_GAIN_SCALE_ADDR};
use imu_proto::reply::Reply;
use tokio::io::AsyncWriteExt;
use tokio_serial::{SerialPort, SerialStream};
use tracing::{error, info, warn};

use super::{BACKOFF, TRIES};
use crate::config::AcquisitionMode;
use crate::pipeline::{GainFallback, Gains, Timebase};
use crate::session::{Daemon, DeviceIdentity, now_ns};
/// Reads of one GainScale before disagreeing values count as a failed read.
const MAX_GAIN_READS: u32 = 5;

/// Why a GainScale could not be read.
#[derive(Debug)]
enum GainReadError {
    /// No exchange succeeded within its tries.
    Exchange(anyhow::Error),
    /// Replies came, but no two consecutive ones agreed on a plausible value.
    Disagree { last: Option<u16> },
}

impl std::fmt::Display for GainReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Exchange(e) => write!(f, "{e:#} ({TRIES} tries)"),
            Self::Disagree { last } => write!(
                f,
                "{MAX_GAIN_READS} reads and no two consecutive ones agreed on a plausible value \
                 (last {})",
                last.map_or("none".to_string(), |v| v.to_string())
            ),
        }
    }
}

/// A GainScale word the device could have: 0 and 0xFFFF are blank EEPROM.
pub fn plausible_gain_scale(value: u16) -> bool {
    value != 0 && value != u16::MAX
}

impl Daemon {
    /// Reads and decodes until a frame with `code` arrives (other frames go through the
    /// pipeline); errors after the reply time-out.
    async fn await_reply(&mut self, port: &mut SerialStream, code: u8) -> anyhow::Result<Reply> {
        let timeout = Duration::from_secs_f64(self.config.device.reply_timeout_s);
        let mut buf = [0u8; 512];
        tokio::time::timeout(timeout, async {
            loop {
                while let Some(ev) = self.link.gx1.next_event() {
                    let (mono, wall) = now_ns();
                    let wanted = match &ev {
                        DecodeEvent::Frame { reply, .. } if reply.code() == code => Some(*reply),
                        _ => None,
                    };
                    self.pipeline.on_event(ev, mono, wall, &mut self.sinks);
                    if let Some(reply) = wanted {
                        return Ok(reply);
                    }
                }
                self.read_into_link(port, &mut buf).await?;
            }
        })
        .await
        .map_err(|_| {
            anyhow!(
                "no reply to command 0x{code:02X} within {:.1} s",
                timeout.as_secs_f64()
            )
        })?
    }

    /// Sends `cmd` and waits for the first reply with its code.
    async fn transact(&mut self, port: &mut SerialStream, cmd: Command) -> anyhow::Result<Reply> {
        port.write_all(&cmd.to_bytes())
            .await
            .context("writing to the device")?;
        self.await_reply(port, cmd.code()).await
    }

    /// One fenced request: drain, a fence exchange with another reply code, then `cmd`;
    /// tried [`TRIES`] times with back-off. The reply is the one to `cmd`, never a late one.
    pub(crate) async fn exchange(
        &mut self,
        port: &mut SerialStream,
        cmd: Command,
    ) -> anyhow::Result<Reply> {
        let fence = if cmd.code() == Command::FirmwareVersion.code() {
            Command::SerialNumber
        } else {
            Command::FirmwareVersion
        };
        let mut last_error = anyhow!("not tried");
        for attempt in 0..TRIES {
            if attempt > 0 {
                tokio::time::sleep(BACKOFF * 2u32.pow(attempt - 1)).await;
            }
            let fenced = async {
                self.drain_until_quiet(port).await?;
                self.transact(port, fence)
                    .await
                    .context("synchronising the line")?;
                self.transact(port, cmd).await
            };
            match fenced.await {
                Ok(reply) => return Ok(reply),
                Err(e) => last_error = e,
            }
        }
        Err(last_error)
    }

    /// Reads one GainScale until two consecutive fenced reads agree on a plausible value.
    async fn read_gain_scale(
        &mut self,
        port: &mut SerialStream,
        address: u16,
    ) -> Result<u16, GainReadError> {
        let mut previous: Option<u16> = None;
        for _ in 0..MAX_GAIN_READS {
            let value = match self.exchange(port, Command::ReadEeprom { address }).await {
                Ok(Reply::EepromRead { value, .. }) => value,
                Ok(_) => continue, // cannot happen: the reply code matched
                Err(e) => return Err(GainReadError::Exchange(e)),
            };
            if !plausible_gain_scale(value) {
                previous = None;
                continue;
            }
            if previous == Some(value) {
                return Ok(value);
            }
            previous = Some(value);
        }
        Err(GainReadError::Disagree { last: previous })
    }

    /// Reads the three GainScales; each one that cannot be read is the configured fallback.
    /// Says once, in one line, which gains are in force and where each came from.
    async fn read_gains(&mut self, port: &mut SerialStream) -> Gains {
        let fb = self.config.device.fallback_gains;
        let mut gains = Gains {
            accel: fb.accel,
            gyro: fb.gyro,
            mag: fb.mag,
            fallback: GainFallback::NONE,
        };
        let mut report = Vec::with_capacity(3);
        let mut any_fallback = false;
        for (name, address) in [
            ("accel", ACCEL_GAIN_SCALE_ADDR),
            ("gyro", GYRO_GAIN_SCALE_ADDR),
            ("mag", MAG_GAIN_SCALE_ADDR),
        ] {
            let (slot, fallback, flag) = match name {
                "accel" => (&mut gains.accel, fb.accel, &mut gains.fallback.accel),
                "gyro" => (&mut gains.gyro, fb.gyro, &mut gains.fallback.gyro),
                _ => (&mut gains.mag, fb.mag, &mut gains.fallback.mag),
            };
            match self.read_gain_scale(port, address).await {
                Ok(value) => {
                    *slot = value;
                    report.push(format!("{name} {value} (device)"));
                }
                Err(why) => {
                    *slot = fallback;
                    *flag = true;
                    any_fallback = true;
                    report.push(format!(
                        "{name} {fallback} (configured FALLBACK: EEPROM word {address} unreadable: {why})"
                    ));
                }
            }
        }
        let report = report.join(", ");
        if any_fallback {
            error!("GainScales in force: {report}; corrected samples are flagged FALLBACK_GAINS");
        } else {
            info!("GainScales in force: {report}");
        }
        gains
    }

    /// Stops any streaming: a blind stop, a pause for in-flight bytes, then a confirmed stop.
    async fn stop_streaming(&mut self, port: &mut SerialStream) -> anyhow::Result<()> {
        let stop = Command::SetContinuous { command: 0 };
        let mut last_error = anyhow!("not tried");
        for attempt in 0..TRIES {
            if attempt > 0 {
                tokio::time::sleep(BACKOFF * 2u32.pow(attempt - 1)).await;
            }
            port.write_all(&stop.to_bytes())
                .await
                .context("writing to the device")?;
            tokio::time::sleep(Duration::from_millis(300)).await;
            let _ = port.clear(tokio_serial::ClearBuffer::Input);
            match self.exchange(port, stop).await {
                Ok(Reply::Continuous { command: 0, .. }) => return Ok(()),
                Ok(other) => {
                    last_error = anyhow!("the device did not confirm stopping: {other:?}");
                }
                Err(e) => last_error = e,
            }
        }
        Err(last_error.context("stopping continuous mode"))
    }

    /// Starts continuous mode with data command `cmd`. Samples of the stream prove it started
    /// when the acknowledgement itself was lost (no fence: a streaming device answers nothing).
    async fn start_streaming(&mut self, port: &mut SerialStream, cmd: u8) -> anyhow::Result<()> {
        self.drain_until_quiet(port).await?;
        let samples_before = self.pipeline.counters().samples;
        let mut last_error = anyhow!("not tried");
        for attempt in 0..TRIES {
            if attempt > 0 {
                tokio::time::sleep(BACKOFF * 2u32.pow(attempt - 1)).await;
            }
            match self
                .transact(port, Command::SetContinuous { command: cmd })
                .await
            {
                Ok(Reply::Continuous { command, .. }) if command == cmd => return Ok(()),
                Ok(other) => {
                    last_error = anyhow!("the device did not confirm continuous mode: {other:?}");
                }
                Err(e) => last_error = e,
            }
            if self.pipeline.counters().samples > samples_before {
                return Ok(());
            }
        }
        Err(last_error.context("starting continuous mode"))
    }

    /// The start-up sequence of the protocol notes, fenced, on an open port.
    pub(super) async fn start_gx1(
        &mut self,
        port: &mut SerialStream,
    ) -> anyhow::Result<DeviceIdentity> {
        let cfg = self.config.device.clone();
        self.stop_streaming(port).await?;
        let firmware = match self.exchange(port, Command::FirmwareVersion).await? {
            Reply::FirmwareVersion { version } => version,
            other => bail!("unexpected firmware reply {other:?}"),
        };
        let serial = match self.exchange(port, Command::SerialNumber).await? {
            Reply::SerialNumber { serial } => serial,
            other => bail!("unexpected serial-number reply {other:?}"),
        };
        let gains = self.read_gains(port).await;
        // One temperature reading before streaming (the device says nothing else while it streams).
        if let Err(e) = self.exchange(port, Command::Temperature).await {
            warn!("no temperature reading at start-up: {e:#}");
        }
        self.pipeline
            .new_session(gains, Timebase::gx1(cfg.tick_period_s));
        let firmware = imu_proto::scale::format_firmware_version(firmware);
        info!(
            "device {} (3DM-GX1) firmware {firmware} serial {serial}",
            cfg.path.display(),
        );
        if cfg.mode == AcquisitionMode::Continuous {
            self.start_streaming(port, cfg.command.command().code())
                .await?;
        }
        self.pipeline
            .set_continuous(cfg.mode == AcquisitionMode::Continuous);
        Ok(DeviceIdentity {
            protocol: DeviceProtocol::Gx1,
            model: "3DM-GX1".into(),
            firmware,
            serial: serial.to_string(),
            gains,
            details: vec![("tick-period-s".into(), cfg.tick_period_s.to_string())],
        })
    }
}
