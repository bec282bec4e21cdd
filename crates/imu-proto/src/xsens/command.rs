//! The host's commands ([`XsensCommand`]) and the unit's replies ([`XsensReply`]), encoded to
//! and decoded from [`Message`]s on both sides.

use super::data::MtData2;
use super::mid;
use super::{Message, XsensError};

/// One output of an output configuration: a data identifier (with its format and frame bits)
/// and its rate, Hz (0xFFFF or 0 mean "every sample" for the time and status items).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct OutputSetting {
    /// The data identifier.
    pub data_id: u16,
    /// Output rate, Hz.
    pub rate_hz: u16,
}

/// The outputs a unit streams (at most [`OutputConfiguration::MAX_OUTPUTS`]).
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct OutputConfiguration(pub Vec<OutputSetting>);

impl OutputConfiguration {
    /// Most outputs one configuration holds (the MT manual's limit).
    pub const MAX_OUTPUTS: usize = 32;

    fn encode(&self) -> Vec<u8> {
        self.0
            .iter()
            .flat_map(|s| {
                let [a, b] = s.data_id.to_be_bytes();
                let [c, d] = s.rate_hz.to_be_bytes();
                [a, b, c, d]
            })
            .collect()
    }

    fn decode(mid: u8, data: &[u8]) -> Result<Self, XsensError> {
        if !data.len().is_multiple_of(4) || data.len() / 4 > Self::MAX_OUTPUTS {
            return Err(XsensError::BadData {
                mid,
                problem: "an output configuration is up to 32 pairs of data id and rate",
            });
        }
        Ok(Self(
            data.chunks_exact(4)
                .map(|c| OutputSetting {
                    data_id: u16::from_be_bytes([c[0], c[1]]),
                    rate_hz: u16::from_be_bytes([c[2], c[3]]),
                })
                .collect(),
        ))
    }
}

/// A firmware revision (`FirmwareRev`, 3 bytes, or 11 with build and SVN revision).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct FirmwareRev {
    /// Major version.
    pub major: u8,
    /// Minor version.
    pub minor: u8,
    /// Revision.
    pub revision: u8,
    /// Build number and SVN revision, when sent.
    pub build: Option<(u32, u32)>,
}

impl std::fmt::Display for FirmwareRev {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.revision)?;
        if let Some((build, rev)) = self.build {
            write!(f, " build {build} rev {rev}")?;
        }
        Ok(())
    }
}

/// A message from the host.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum XsensCommand {
    /// Answer to `WakeUp`: stay in config mode.
    WakeUpAck,
    /// Switch to config mode (stops the stream).
    GoToConfig,
    /// Switch to measurement mode (starts the stream).
    GoToMeasurement,
    /// Ask the device id.
    ReqDeviceId,
    /// Ask the product code.
    ReqProductCode,
    /// Ask the firmware revision.
    ReqFirmwareRev,
    /// Set the outputs and their rates.
    SetOutputConfiguration(OutputConfiguration),
    /// Ask the output configuration.
    ReqOutputConfiguration,
    /// Reset the unit.
    Reset,
}

impl XsensCommand {
    /// The message.
    pub fn to_message(&self) -> Message {
        let (m, data) = match self {
            XsensCommand::WakeUpAck => (mid::WAKE_UP_ACK, Vec::new()),
            XsensCommand::GoToConfig => (mid::GO_TO_CONFIG, Vec::new()),
            XsensCommand::GoToMeasurement => (mid::GO_TO_MEASUREMENT, Vec::new()),
            XsensCommand::ReqDeviceId => (mid::REQ_DID, Vec::new()),
            XsensCommand::ReqProductCode => (mid::REQ_PRODUCT_CODE, Vec::new()),
            XsensCommand::ReqFirmwareRev => (mid::REQ_FW_REV, Vec::new()),
            XsensCommand::SetOutputConfiguration(c) => (mid::SET_OUTPUT_CONFIGURATION, c.encode()),
            XsensCommand::ReqOutputConfiguration => (mid::SET_OUTPUT_CONFIGURATION, Vec::new()),
            XsensCommand::Reset => (mid::RESET, Vec::new()),
        };
        // At most 32 x 4 bytes of data: always fits.
        Message::new(m, &data).expect("a command fits one message")
    }

    /// The command a message carries (device side).
    pub fn decode(msg: &Message) -> Result<Self, XsensError> {
        let data = msg.data();
        let none = |c: XsensCommand| {
            if data.is_empty() {
                Ok(c)
            } else {
                Err(XsensError::BadData {
                    mid: msg.mid(),
                    problem: "this request carries no data",
                })
            }
        };
        match msg.mid() {
            mid::WAKE_UP_ACK => none(XsensCommand::WakeUpAck),
            mid::GO_TO_CONFIG => none(XsensCommand::GoToConfig),
            mid::GO_TO_MEASUREMENT => none(XsensCommand::GoToMeasurement),
            mid::REQ_DID => none(XsensCommand::ReqDeviceId),
            mid::REQ_PRODUCT_CODE => none(XsensCommand::ReqProductCode),
            mid::REQ_FW_REV => none(XsensCommand::ReqFirmwareRev),
            mid::RESET => none(XsensCommand::Reset),
            mid::SET_OUTPUT_CONFIGURATION if data.is_empty() => {
                Ok(XsensCommand::ReqOutputConfiguration)
            }
            mid::SET_OUTPUT_CONFIGURATION => Ok(XsensCommand::SetOutputConfiguration(
                OutputConfiguration::decode(msg.mid(), data)?,
            )),
            other => Err(XsensError::UnknownMessage(other)),
        }
    }
}

/// A message from the unit.
#[derive(Debug, Clone, PartialEq)]
pub enum XsensReply {
    /// Sent at power-up.
    WakeUp,
    /// Config mode entered.
    GoToConfigAck,
    /// Measurement mode entered.
    GoToMeasurementAck,
    /// The device id (the serial number).
    DeviceId(u64),
    /// The product code (the model), trailing spaces and NULs removed.
    ProductCode(String),
    /// The firmware revision.
    FirmwareRev(FirmwareRev),
    /// The output configuration in force.
    OutputConfiguration(OutputConfiguration),
    /// Reset acknowledged.
    ResetAck,
    /// An error code.
    Error(u8),
    /// A data message (boxed: the other replies are small; the per-sample path decodes
    /// [`MtData2`] directly).
    MtData2(Box<MtData2>),
}

/// The meaning of an error code (`mtdef.py` `MTErrorMessage`).
pub fn error_name(code: u8) -> &'static str {
    match code {
        3 => "period sent is invalid",
        4 => "message is invalid or not implemented",
        30 => "timer overflow during measurement",
        32 => "baud rate out of range",
        33 => "invalid parameter",
        40 => "device error, try updating the firmware",
        41 => "device generates more data than the bus can carry (baud rate too low)",
        42 => "sample buffer full during a communication outage",
        _ => "unknown error code",
    }
}

impl XsensReply {
    /// The message.
    pub fn to_message(&self) -> Message {
        let (m, data): (u8, Vec<u8>) = match self {
            XsensReply::WakeUp => (mid::WAKE_UP, Vec::new()),
            XsensReply::GoToConfigAck => (mid::GO_TO_CONFIG_ACK, Vec::new()),
            XsensReply::GoToMeasurementAck => (mid::GO_TO_MEASUREMENT_ACK, Vec::new()),
            XsensReply::DeviceId(id) => match u32::try_from(*id) {
                Ok(short) => (mid::DEVICE_ID, short.to_be_bytes().to_vec()),
                Err(_) => (mid::DEVICE_ID, id.to_be_bytes().to_vec()),
            },
            XsensReply::ProductCode(code) => (
                mid::PRODUCT_CODE,
                code.bytes().take(super::MAX_SHORT_DATA_LEN).collect(),
            ),
            XsensReply::FirmwareRev(fw) => {
                let mut d = vec![fw.major, fw.minor, fw.revision];
                if let Some((build, svn)) = fw.build {
                    d.extend_from_slice(&build.to_be_bytes());
                    d.extend_from_slice(&svn.to_be_bytes());
                }
                (mid::FIRMWARE_REV, d)
            }
            XsensReply::OutputConfiguration(c) => (mid::OUTPUT_CONFIGURATION, c.encode()),
            XsensReply::ResetAck => (mid::RESET_ACK, Vec::new()),
            XsensReply::Error(code) => (mid::ERROR, vec![*code]),
            XsensReply::MtData2(d) => {
                return d.to_message(super::data::Format::Float32);
            }
        };
        Message::new(m, &data).expect("a reply fits one message")
    }

    /// The reply a message carries (host side).
    pub fn decode(msg: &Message) -> Result<Self, XsensError> {
        let data = msg.data();
        let m = msg.mid();
        let bad = |problem| XsensError::BadData { mid: m, problem };
        let none = |r: XsensReply| {
            if data.is_empty() {
                Ok(r)
            } else {
                Err(bad("this acknowledgement carries no data"))
            }
        };
        match m {
            mid::WAKE_UP => none(XsensReply::WakeUp),
            mid::GO_TO_CONFIG_ACK => none(XsensReply::GoToConfigAck),
            mid::GO_TO_MEASUREMENT_ACK => none(XsensReply::GoToMeasurementAck),
            mid::RESET_ACK => none(XsensReply::ResetAck),
            mid::DEVICE_ID => match data.len() {
                4 => Ok(XsensReply::DeviceId(u64::from(u32::from_be_bytes([
                    data[0], data[1], data[2], data[3],
                ])))),
                8 => Ok(XsensReply::DeviceId(u64::from_be_bytes(
                    data.try_into()
                        .map_err(|_| bad("device id of 4 or 8 bytes"))?,
                ))),
                _ => Err(bad("device id of 4 or 8 bytes")),
            },
            mid::PRODUCT_CODE => {
                let text = std::str::from_utf8(data).map_err(|_| bad("product code not ASCII"))?;
                Ok(XsensReply::ProductCode(
                    text.trim_end_matches([' ', '\0']).to_string(),
                ))
            }
            mid::FIRMWARE_REV => match data.len() {
                3 | 11 => Ok(XsensReply::FirmwareRev(FirmwareRev {
                    major: data[0],
                    minor: data[1],
                    revision: data[2],
                    build: (data.len() == 11).then(|| {
                        (
                            u32::from_be_bytes([data[3], data[4], data[5], data[6]]),
                            u32::from_be_bytes([data[7], data[8], data[9], data[10]]),
                        )
                    }),
                })),
                _ => Err(bad("firmware revision of 3 or 11 bytes")),
            },
            mid::OUTPUT_CONFIGURATION => Ok(XsensReply::OutputConfiguration(
                OutputConfiguration::decode(m, data)?,
            )),
            // Newer firmware may follow the code with more bytes; the code is the first.
            mid::ERROR => match data.first() {
                Some(&code) => Ok(XsensReply::Error(code)),
                None => Err(bad("error message without a code")),
            },
            mid::MT_DATA2 => Ok(XsensReply::MtData2(Box::new(MtData2::decode_data(data)?))),
            other => Err(XsensError::UnknownMessage(other)),
        }
    }
}
