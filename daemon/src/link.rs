//! The byte stream's decoders, one per protocol, behind one face: the session pushes what the
//! port read and drains complete events into the pipeline, whatever the device speaks.
//!
//! Both decoders are kept for the daemon's life, so the status's fault counters stay
//! cumulative across reconnects even when a probe finds another protocol on the port.

use imu_proto::DeviceProtocol;
use imu_proto::decoder::{DecodeEvent, DecoderStats, ReplyDecoder};
use imu_proto::mip::MipDecoder;

use crate::pipeline::{Pipeline, Sinks, log_rejected};

/// The decoders and which one the current session feeds.
#[derive(Debug, Default)]
pub struct Link {
    protocol: DeviceProtocol,
    /// The 3DM-GX1 decoder.
    pub gx1: ReplyDecoder,
    /// The MIP decoder.
    pub mip: MipDecoder,
}

impl Link {
    /// Decoders for a device speaking `protocol` (until [`Link::set_protocol`]).
    pub fn new(protocol: DeviceProtocol) -> Self {
        Self {
            protocol,
            ..Self::default()
        }
    }

    /// The protocol the session speaks.
    pub fn protocol(&self) -> DeviceProtocol {
        self.protocol
    }

    /// Feeds the other decoder from now on (the current one's partial frame is flushed first).
    pub fn set_protocol(&mut self, protocol: DeviceProtocol) {
        if protocol != self.protocol {
            self.flush();
            self.protocol = protocol;
        }
    }

    /// Bytes from the port.
    pub fn push(&mut self, bytes: &[u8]) {
        match self.protocol {
            DeviceProtocol::Gx1 => self.gx1.push(bytes),
            DeviceProtocol::Mip => self.mip.push(bytes),
        }
    }

    /// Ends any partial frame (it is rejected as truncated when the next event is taken).
    pub fn flush(&mut self) {
        match self.protocol {
            DeviceProtocol::Gx1 => self.gx1.flush(),
            DeviceProtocol::Mip => self.mip.flush(),
        }
    }

    /// Every complete event to the pipeline, stamped with the host times of the read.
    pub fn drain_into(
        &mut self,
        pipeline: &mut Pipeline,
        mono_ns: u64,
        wall_ns: u64,
        sinks: &mut Sinks,
    ) {
        match self.protocol {
            DeviceProtocol::Gx1 => {
                while let Some(ev) = self.gx1.next_event() {
                    pipeline.on_event(ev, mono_ns, wall_ns, sinks);
                }
            }
            DeviceProtocol::Mip => {
                while let Some(ev) = self.mip.next_event() {
                    pipeline.on_mip_event(ev, mono_ns, wall_ns, sinks);
                }
            }
        }
    }

    /// Every complete event to the pipeline's log as frames only: no samples (the start-up's
    /// bytes before the session's clock is set).
    pub fn log_into(&mut self, pipeline: &mut Pipeline, mono_ns: u64, wall_ns: u64, sinks: &Sinks) {
        match self.protocol {
            DeviceProtocol::Gx1 => {
                while let Some(ev) = self.gx1.next_event() {
                    match ev {
                        DecodeEvent::Frame { bytes, offset, .. } => {
                            pipeline.log_frame(&bytes, offset, mono_ns, wall_ns, sinks);
                        }
                        DecodeEvent::Rejected {
                            bytes,
                            offset,
                            reason,
                        } => {
                            log_rejected(bytes, offset, reason, mono_ns, wall_ns, sinks);
                        }
                    }
                }
            }
            DeviceProtocol::Mip => {
                while let Some(ev) = self.mip.next_event() {
                    pipeline.log_mip_event(ev, mono_ns, wall_ns, sinks);
                }
            }
        }
    }

    /// Both decoders' counters, summed.
    pub fn stats(&self) -> DecoderStats {
        let (a, b) = (self.gx1.stats(), self.mip.stats());
        DecoderStats {
            frames: a.frames + b.frames,
            bytes_in: a.bytes_in + b.bytes_in,
            frame_bytes: a.frame_bytes + b.frame_bytes,
            rejected_bytes: a.rejected_bytes + b.rejected_bytes,
            garbage_bytes: a.garbage_bytes + b.garbage_bytes,
            checksum_failures: a.checksum_failures + b.checksum_failures,
            malformed_frames: a.malformed_frames + b.malformed_frames,
            truncated_frames: a.truncated_frames + b.truncated_frames,
            resyncs: a.resyncs + b.resyncs,
        }
    }
}
