//! The device the link runs, by protocol: one enum over the 3DM-GX1 ([`DeviceCore`] with its
//! command decoder), the MIP unit ([`MipDevice`]), the Xsens MTi ([`XsensDevice`]) and the
//! VectorNav unit ([`VnDevice`]), so the pty loop in [`crate::link`] knows no protocol. Another
//! protocol is another variant here and a device file beside these.

use imu_proto::DeviceProtocol;
use imu_proto::command::Command;
use imu_proto::decoder::{CommandDecoder, CommandEvent};
use imu_rec::truth::TruthSample;

use crate::device::DeviceCore;
use crate::mip_device::{MipDevice, MipRequest};
use crate::vectornav_device::{VnDevice, VnRequest};
use crate::xsens_device::{XsensDevice, XsensRequest};

/// A running virtual device of either protocol.
pub enum VirtualDevice {
    /// The 3DM-GX1.
    Gx1 {
        /// Physics, truth and the GX1's command semantics.
        core: DeviceCore,
        /// Commands from the host.
        decoder: CommandDecoder,
    },
    /// A MIP unit.
    Mip(MipDevice),
    /// An Xsens MTi.
    Xsens(XsensDevice),
    /// A VectorNav unit.
    Vectornav(VnDevice),
}

/// One command from the host, in its protocol's terms.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// A GX1 command.
    Gx1(Command),
    /// A MIP command field.
    Mip(MipRequest),
    /// An Xsens message.
    Xsens(XsensRequest),
    /// A VectorNav sentence.
    Vectornav(VnRequest),
}

impl Request {
    /// A data request starts the scenario clock (GX1 polls and continuous mode); a MIP unit
    /// starts it when it starts streaming.
    pub fn is_data(&self) -> bool {
        match self {
            Request::Gx1(c) => c.is_data(),
            Request::Mip(_) | Request::Xsens(_) | Request::Vectornav(_) => false,
        }
    }
}

/// The device's answer to one request.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Answer {
    /// Bytes to send (empty: the device stays silent).
    pub bytes: Vec<u8>,
    /// The truth behind a data reply.
    pub truth: Option<TruthSample>,
    /// How long the real device takes before it answers, seconds.
    pub delay_s: f64,
}

impl VirtualDevice {
    /// The device of `protocol` around `core`.
    pub fn new(protocol: DeviceProtocol, core: DeviceCore) -> Self {
        match protocol {
            DeviceProtocol::Gx1 => VirtualDevice::Gx1 {
                core,
                decoder: CommandDecoder::new(),
            },
            DeviceProtocol::Mip => VirtualDevice::Mip(MipDevice::new(core)),
            DeviceProtocol::Xsens => VirtualDevice::Xsens(XsensDevice::new(core)),
            DeviceProtocol::Vectornav => VirtualDevice::Vectornav(VnDevice::new(core)),
        }
    }

    /// Physics, truth and scenario.
    pub fn core(&self) -> &DeviceCore {
        match self {
            VirtualDevice::Gx1 { core, .. } => core,
            VirtualDevice::Mip(d) => d.core(),
            VirtualDevice::Xsens(d) => d.core(),
            VirtualDevice::Vectornav(d) => d.core(),
        }
    }

    /// Bytes from the host.
    pub fn push(&mut self, bytes: &[u8]) {
        match self {
            VirtualDevice::Gx1 { decoder, .. } => decoder.push(bytes),
            VirtualDevice::Mip(d) => d.push(bytes),
            VirtualDevice::Xsens(d) => d.push(bytes),
            VirtualDevice::Vectornav(d) => d.push(bytes),
        }
    }

    /// Host bytes not yet decoded.
    pub fn pending_len(&self) -> usize {
        match self {
            VirtualDevice::Gx1 { decoder, .. } => decoder.pending_len(),
            VirtualDevice::Mip(d) => d.pending_len(),
            VirtualDevice::Xsens(d) => d.pending_len(),
            VirtualDevice::Vectornav(d) => d.pending_len(),
        }
    }

    /// The host stopped inside a command: drop it, as a device would. Returns the bytes
    /// rejected now (a MIP unit reports them through [`next_request`](Self::next_request)).
    pub fn expire_partial(&mut self) -> u64 {
        match self {
            VirtualDevice::Gx1 { decoder, .. } => match decoder.expire_partial() {
                Some(CommandEvent::Rejected { bytes, .. }) => bytes.len() as u64,
                _ => 0,
            },
            VirtualDevice::Mip(d) => {
                d.expire_partial();
                0
            }
            VirtualDevice::Xsens(d) => {
                d.expire_partial();
                0
            }
            VirtualDevice::Vectornav(d) => {
                d.expire_partial();
                0
            }
        }
    }

    /// The cable was pulled: half-received commands are gone.
    pub fn reset_link(&mut self) {
        match self {
            VirtualDevice::Gx1 { decoder, .. } => *decoder = CommandDecoder::new(),
            VirtualDevice::Mip(d) => d.reset_link(),
            VirtualDevice::Xsens(d) => d.reset_link(),
            VirtualDevice::Vectornav(d) => d.reset_link(),
        }
    }

    /// The next command, or `Err(n)` for `n` bytes that were not one.
    pub fn next_request(&mut self) -> Option<Result<Request, u64>> {
        match self {
            VirtualDevice::Gx1 { decoder, .. } => Some(match decoder.next_event()? {
                CommandEvent::Command(c) => Ok(Request::Gx1(c)),
                CommandEvent::Rejected { bytes, .. } => Err(bytes.len() as u64),
            }),
            VirtualDevice::Mip(d) => Some(d.next_request()?.map(Request::Mip)),
            VirtualDevice::Xsens(d) => Some(d.next_request()?.map(Request::Xsens)),
            VirtualDevice::Vectornav(d) => Some(d.next_request()?.map(Request::Vectornav)),
        }
    }

    /// Answers one request at scenario time `t_s`.
    pub fn handle(&mut self, request: Request, t_s: f64) -> Answer {
        match (self, request) {
            (VirtualDevice::Gx1 { core, .. }, Request::Gx1(cmd)) => {
                let r = core.handle(cmd, t_s);
                Answer {
                    bytes: r.reply.map(|reply| reply.to_bytes()).unwrap_or_default(),
                    truth: r.truth,
                    delay_s: r.delay_s,
                }
            }
            (VirtualDevice::Mip(d), Request::Mip(req)) => Answer {
                bytes: d.handle(req).as_bytes().to_vec(),
                truth: None,
                delay_s: 0.0,
            },
            (VirtualDevice::Xsens(d), Request::Xsens(req)) => Answer {
                bytes: d
                    .handle(req)
                    .map(|m| m.as_bytes().to_vec())
                    .unwrap_or_default(),
                truth: None,
                delay_s: 0.0,
            },
            (VirtualDevice::Vectornav(d), Request::Vectornav(req)) => Answer {
                bytes: d.handle(req),
                truth: None,
                delay_s: 0.0,
            },
            // A request comes from the same device's decoder, so the protocols always match.
            _ => Answer::default(),
        }
    }

    /// True while the device sends data on its own.
    pub fn is_streaming(&self) -> bool {
        match self {
            VirtualDevice::Gx1 { core, .. } => core.streaming().is_some(),
            VirtualDevice::Mip(d) => d.is_streaming(),
            VirtualDevice::Xsens(d) => d.is_streaming(),
            VirtualDevice::Vectornav(d) => d.is_streaming(),
        }
    }

    /// Appends the streamed sample due at `t_s` to `out`; its truth record. `None` when the
    /// device is not streaming.
    pub fn stream_sample(&mut self, t_s: f64, out: &mut Vec<u8>) -> Option<TruthSample> {
        match self {
            VirtualDevice::Gx1 { core, .. } => {
                let cmd = core.streaming()?;
                let (reply, truth) = core.data_reply(cmd, t_s);
                reply.encode(out);
                Some(truth)
            }
            VirtualDevice::Mip(d) => {
                if !d.is_streaming() {
                    return None;
                }
                let (packet, truth) = d.data_packet(t_s);
                out.extend_from_slice(packet.as_bytes());
                Some(truth)
            }
            VirtualDevice::Xsens(d) => {
                if !d.is_streaming() {
                    return None;
                }
                let (msg, truth) = d.data_message(t_s);
                out.extend_from_slice(msg.as_bytes());
                Some(truth)
            }
            VirtualDevice::Vectornav(d) => d.stream_sample(t_s, out),
        }
    }

    /// The line rate the link is paced to in real time, bits/s; `None`: not paced (a MIP,
    /// Xsens or VectorNav unit on a USB virtual serial port).
    pub fn baud(&self) -> Option<u32> {
        match self {
            VirtualDevice::Gx1 { core, .. } => Some(core.scenario().device.baud),
            VirtualDevice::Mip(_) | VirtualDevice::Xsens(_) | VirtualDevice::Vectornav(_) => None,
        }
    }
}
