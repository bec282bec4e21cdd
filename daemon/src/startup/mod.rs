//! The device start-up sequence: open the port, find out which protocol the device speaks
//! (configured, or probed), and run that protocol's sequence (`gx1.rs`, `mip.rs`), which
//! leaves the device streaming and the pipeline set for its session.
//!
//! A third protocol adds a file here with its sequence, a branch in [`Daemon::open_and_start`]
//! and a question in `probe.rs`.

mod gx1;
mod mip;
mod probe;

use std::time::Duration;

use anyhow::{Context, anyhow, bail};
use imu_proto::DeviceProtocol;
use tokio::io::AsyncReadExt;
use tokio_serial::{SerialPortBuilderExt, SerialStream};

use crate::session::{Daemon, DeviceIdentity, now_ns};

pub use gx1::plausible_gain_scale;
pub use mip::preferred_mip_format;

/// Tries of one exchange before it counts as failed.
pub const TRIES: u32 = 3;
/// Back-off before the second try; doubled before each further one.
const BACKOFF: Duration = Duration::from_millis(200);
/// Silence that counts as a quiet line.
const QUIET: Duration = Duration::from_millis(50);
/// Longest drain before a request (a line that never goes quiet is still streaming).
const MAX_DRAIN: Duration = Duration::from_secs(1);

impl Daemon {
    /// Feeds every complete decoder event to the pipeline (frames are logged and data
    /// published as usual).
    fn feed_pipeline(&mut self) {
        let (mono, wall) = now_ns();
        self.link
            .drain_into(&mut self.pipeline, mono, wall, &mut self.sinks);
    }

    /// Reads until the line has been silent for [`QUIET`] (at most [`MAX_DRAIN`]), then ends any
    /// partial frame in the decoder, so stale bytes are logged and forgotten.
    async fn drain_until_quiet(&mut self, port: &mut SerialStream) -> anyhow::Result<()> {
        let deadline = tokio::time::Instant::now() + MAX_DRAIN;
        let mut buf = [0u8; 512];
        while tokio::time::Instant::now() < deadline {
            match tokio::time::timeout(QUIET, port.read(&mut buf)).await {
                Err(_) => break, // quiet
                Ok(Ok(0)) => bail!("the device closed the line"),
                Ok(Ok(n)) => {
                    self.link.push(&buf[..n]);
                    self.feed_pipeline();
                }
                Ok(Err(e)) => return Err(anyhow!(e).context("reading from the device")),
            }
        }
        self.link.flush();
        self.feed_pipeline();
        Ok(())
    }

    /// Reads what the port has into the link (waiting for at least one byte).
    async fn read_into_link(
        &mut self,
        port: &mut SerialStream,
        buf: &mut [u8],
    ) -> anyhow::Result<()> {
        let n = port.read(buf).await.context("reading from the device")?;
        if n == 0 {
            bail!("the device closed the line");
        }
        self.link.push(&buf[..n]);
        Ok(())
    }

    /// Opens the port, settles the protocol and runs its start-up sequence.
    pub(crate) async fn open_and_start(
        &mut self,
    ) -> anyhow::Result<(SerialStream, DeviceIdentity)> {
        let cfg = self.config.device.clone();
        let mut port = tokio_serial::new(cfg.path.to_string_lossy(), cfg.baud)
            .open_native_async()
            .with_context(|| format!("opening {}", cfg.path.display()))?;
        let protocol = match cfg.protocol {
            Some(p) => p,
            None => self.probe(&mut port).await?,
        };
        self.link.set_protocol(protocol);
        let identity = match protocol {
            DeviceProtocol::Gx1 => self.start_gx1(&mut port).await?,
            DeviceProtocol::Mip => self.start_mip(&mut port).await?,
        };
        Ok((port, identity))
    }
}

/// Waits `attempt`'s back-off before a retry (none before the first try).
async fn back_off(attempt: u32) {
    if attempt > 0 {
        tokio::time::sleep(BACKOFF * 2u32.pow(attempt - 1)).await;
    }
}

/// An error for a reply that never came.
fn no_reply(what: &str, timeout: Duration) -> anyhow::Error {
    anyhow!("no reply to {what} within {:.1} s", timeout.as_secs_f64())
}
