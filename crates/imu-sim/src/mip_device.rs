//! The virtual device speaking MIP (as a 3DM-GX5 would), sans-IO: the same physics, truth
//! model, noise and truth records as the 3DM-GX1 ([`DeviceCore`]), behind the MIP codec of
//! `imu_proto::mip`, used here the other way round from the host.
//!
//! What a host can rely on:
//! - The unit powers up idle, with data streaming enabled and the IMU message format holding
//!   scaled accel (0x04), scaled gyro (0x05), scaled mag (0x06) and the reference time (0xD5),
//!   each at decimation [`MIP_IMU_BASE_RATE_HZ`] / `rate-hz`; it streams once it is resumed (or
//!   the stream is enabled again after `resume`). Set-to-idle stops it; resume restarts it.
//!   With the scenario's `device.power-up-streaming` it powers up already streaming (a unit
//!   set up and saved with the vendor's tool).
//! - Scaled vectors are the measured values (truth model + noise) as f32 in g, rad/s and gauss;
//!   delta theta and delta velocity are the sample's rate and acceleration times the sample
//!   period (the device integrates nothing finer); raw fields are the GX1's nominal raw-bit
//!   counts of the same values, as floats; the temperature field gives min, max and mean of the
//!   true temperature over the samples sent so far; the GPS timestamp is device time since
//!   power-on, its valid flags clear (no GNSS), unless the scenario's `device.gnss-time` is
//!   set: then it is the sample's true UTC time as GPS week and time of week, time-of-week and
//!   week valid, and during a `device.gnss-outage` the flags drop and the time is the unit's
//!   own propagation on its drifting clock from the last fix (`DeviceCore::gnss_time`). Such a unit powers up with
//!   the GPS timestamp in its IMU message format.
//! - Timestamps follow the device's own oscillator (the scenario's clock drift): the reference
//!   time (0xD5) in ns since power-on, the internal timestamp (0x0E) in counts of
//!   [`INTERNAL_TICK_HZ`]. The truth record's `ticks_unwrapped` is the internal timestamp
//!   count (`ticks` its low 16 bits) and its `command` is the data set, 0x80.
//! - It answers the legacy IMU commands (get IMU base rate 0x06, IMU message format 0x08) and
//!   their generic forms for the IMU data set (get base rate 0x0E, message format 0x0F).
//! - The unit streams only at the scenario's rate: a message format asking for another
//!   decimation, or a field it cannot make, is nacked with "invalid parameter" and changes
//!   nothing. Unknown commands are nacked with "unknown command".

use std::collections::VecDeque;

use imu_proto::mip::command::cmd_3dm;
use imu_proto::mip::data::{INTERNAL_TICK_HZ, field};
use imu_proto::mip::descriptor_set::IMU_DATA;
use imu_proto::mip::{
    AckCode, DescriptorRate, DeviceInfo, GpsTime, ImuData, MessageFormat, MipCommand, MipDecoder,
    MipError, MipEvent, MipReply, Packet, Response, Setting, TemperatureStats,
};
use imu_proto::{gnss_time, scale};
use imu_rec::truth::TruthSample;

use crate::device::{DeviceCore, Measurement};
use crate::scenario::MIP_IMU_BASE_RATE_HZ;

/// Fields the simulated unit can stream.
const SUPPORTED_FIELDS: [u8; 12] = [
    field::RAW_ACCEL,
    field::RAW_GYRO,
    field::RAW_MAG,
    field::SCALED_ACCEL,
    field::SCALED_GYRO,
    field::SCALED_MAG,
    field::DELTA_THETA,
    field::DELTA_VELOCITY,
    field::INTERNAL_TIMESTAMP,
    field::GPS_TIMESTAMP,
    field::TEMPERATURE_ABS,
    field::REFERENCE_TIME,
];

/// Seconds in a GPS week.
const GPS_WEEK_S: f64 = 604_800.0;
/// The GPS timestamp's valid flags for time of week (bit 3) and week number (bit 4)
/// (mip_sdk `data_sensor.h`).
const GPS_TOW_AND_WEEK_VALID: u16 = 8 | 16;

/// One command field taken from a packet: its set and descriptor (for the ack) and the
/// decoded command or why it was not understood.
#[derive(Debug, Clone, PartialEq)]
pub struct MipRequest {
    set: u8,
    descriptor: u8,
    command: Result<MipCommand, MipError>,
}

impl MipRequest {
    /// The command's (descriptor set, field descriptor), as its reply echoes them.
    pub fn descriptor(&self) -> (u8, u8) {
        (self.set, self.descriptor)
    }
}

/// The model name the simulated unit reports in its device information.
pub const MODEL_NAME: &str = "imu-sim MIP";

/// The sans-IO MIP device.
pub struct MipDevice {
    core: DeviceCore,
    decoder: MipDecoder,
    requests: VecDeque<MipRequest>,
    format: MessageFormat,
    stream_enabled: bool,
    idle: bool,
    temperature: Option<(TemperatureStats, u64)>,
}

impl MipDevice {
    /// A powered-on unit around the physics of `core`: idle, or streaming its default IMU
    /// format if the scenario's device powers up streaming (saved so with the vendor's tool).
    pub fn new(core: DeviceCore) -> Self {
        let decimation = decimation_for(core.scenario().rate_hz);
        let idle = !core.scenario().device.power_up_streaming;
        Self {
            decoder: MipDecoder::new(),
            requests: VecDeque::new(),
            format: default_format(decimation, core.scenario().device.gnss_time),
            stream_enabled: true,
            idle,
            temperature: None,
            core,
        }
    }

    /// The physics and truth behind the unit.
    pub fn core(&self) -> &DeviceCore {
        &self.core
    }

    /// The one decimation the unit streams at: base rate / scenario rate.
    pub fn decimation(&self) -> u16 {
        decimation_for(self.core.scenario().rate_hz)
    }

    /// The IMU message format in force.
    pub fn format(&self) -> &MessageFormat {
        &self.format
    }

    /// True while the unit sends data on its own.
    pub fn is_streaming(&self) -> bool {
        !self.idle && self.stream_enabled && !self.format.fields.is_empty()
    }

    /// Bytes from the host.
    pub fn push(&mut self, bytes: &[u8]) {
        self.decoder.push(bytes);
    }

    /// Host bytes not yet part of a packet or a rejected run.
    pub fn pending_len(&self) -> usize {
        self.decoder.pending_len()
    }

    /// The host stopped sending inside a packet: report what is pending (the next
    /// [`next_request`](Self::next_request) calls give it back as rejected bytes).
    pub fn expire_partial(&mut self) {
        self.decoder.flush();
    }

    /// The link was replugged: what was half received is gone.
    pub fn reset_link(&mut self) {
        self.decoder = MipDecoder::new();
        self.requests.clear();
    }

    /// The next command from the host, or `Err(n)` for `n` rejected bytes.
    pub fn next_request(&mut self) -> Option<Result<MipRequest, u64>> {
        loop {
            if let Some(r) = self.requests.pop_front() {
                return Some(Ok(r));
            }
            match self.decoder.next_event()? {
                MipEvent::Rejected { bytes, .. } => return Some(Err(bytes.len() as u64)),
                MipEvent::Packet { packet, .. } => self.requests.extend(
                    MipCommand::decode_packet(&packet).map(|(descriptor, command)| MipRequest {
                        set: packet.descriptor_set(),
                        descriptor,
                        command,
                    }),
                ),
            }
        }
    }

    /// Answers one command: the reply packet.
    pub fn handle(&mut self, request: MipRequest) -> Packet {
        let key = (request.set, request.descriptor);
        let reply = match request.command {
            Ok(cmd) => self.handle_command(cmd),
            Err(MipError::UnknownCommand { .. }) => MipReply::ack(key, AckCode::UnknownCommand),
            Err(_) => MipReply::ack(key, AckCode::InvalidParameter),
        };
        reply.to_packet()
    }

    fn handle_command(&mut self, cmd: MipCommand) -> MipReply {
        let key = cmd.descriptor();
        let ok = |response: Option<Response>| MipReply {
            response,
            ..MipReply::ack(key, AckCode::Ok)
        };
        match cmd {
            MipCommand::Ping => ok(None),
            MipCommand::SetToIdle => {
                self.idle = true;
                ok(None)
            }
            MipCommand::Resume => {
                self.idle = false;
                ok(None)
            }
            MipCommand::GetDeviceInfo => ok(Some(Response::DeviceInfo(self.device_info()))),
            MipCommand::GetImuBaseRate => ok(Some(Response::ImuBaseRate {
                rate_hz: MIP_IMU_BASE_RATE_HZ as u16,
            })),
            MipCommand::GetBaseRate { descriptor_set } if descriptor_set == IMU_DATA => {
                ok(Some(Response::BaseRate {
                    descriptor_set,
                    rate_hz: MIP_IMU_BASE_RATE_HZ as u16,
                }))
            }
            MipCommand::ImuMessageFormat(setting) => self.message_format(setting, key),
            MipCommand::MessageFormat {
                descriptor_set,
                setting,
            } if descriptor_set == IMU_DATA => self.message_format(setting, key),
            // Only the IMU data set exists here.
            MipCommand::GetBaseRate { .. } | MipCommand::MessageFormat { .. } => {
                MipReply::ack(key, AckCode::InvalidParameter)
            }
            MipCommand::DataStream {
                descriptor_set,
                setting,
            } => {
                if descriptor_set != IMU_DATA {
                    return MipReply::ack(key, AckCode::InvalidParameter);
                }
                match setting {
                    Setting::Write(enable) => self.stream_enabled = enable,
                    Setting::Read => {
                        return ok(Some(Response::DataStream {
                            descriptor_set,
                            enabled: self.stream_enabled,
                        }));
                    }
                    Setting::Save => {}
                    Setting::Load | Setting::Reset => self.stream_enabled = true,
                }
                ok(None)
            }
        }
    }

    /// The IMU message format, by the legacy (0x08) or the generic (0x0F) command `key`.
    fn message_format(&mut self, setting: Setting<MessageFormat>, key: (u8, u8)) -> MipReply {
        match setting {
            Setting::Write(format) => {
                let decimation = self.decimation();
                let usable = format.fields.iter().all(|f| {
                    SUPPORTED_FIELDS.contains(&f.descriptor) && f.decimation == decimation
                });
                if !usable {
                    return MipReply::ack(key, AckCode::InvalidParameter);
                }
                self.format = format;
            }
            Setting::Read => {
                let format = self.format.clone();
                let response = if key.1 == cmd_3dm::MESSAGE_FORMAT {
                    Response::MessageFormat {
                        descriptor_set: IMU_DATA,
                        format,
                    }
                } else {
                    Response::ImuMessageFormat(format)
                };
                return MipReply {
                    response: Some(response),
                    ..MipReply::ack(key, AckCode::Ok)
                };
            }
            Setting::Save => {}
            Setting::Load | Setting::Reset => {
                self.format =
                    default_format(self.decimation(), self.core.scenario().device.gnss_time);
            }
        }
        MipReply::ack(key, AckCode::Ok)
    }

    fn device_info(&self) -> DeviceInfo {
        let d = &self.core.scenario().device;
        DeviceInfo {
            firmware_version: d.firmware,
            model_name: MODEL_NAME.into(),
            model_number: "imu-sim".into(),
            serial_number: d.serial_number.to_string(),
            lot_number: String::new(),
            device_options: String::new(),
        }
    }

    /// The data packet due at scenario time `t_s`, with its truth record.
    pub fn data_packet(&mut self, t_s: f64) -> (Packet, TruthSample) {
        let m = self.core.measure(t_s, true);
        let device_time_s = self.core.device_time_s(t_s);
        let ticks = (device_time_s * INTERNAL_TICK_HZ).floor().max(0.0) as u64;
        let data = self.imu_data(&m, t_s, device_time_s, ticks);
        let truth = self.core.truth_sample(&m, IMU_DATA, ticks, false);
        (data.to_packet(), truth)
    }

    /// The fields of the message format, made from `m`.
    fn imu_data(&mut self, m: &Measurement, t_s: f64, device_time_s: f64, ticks: u64) -> ImuData {
        let g0 = imu_model::units::STANDARD_GRAVITY_M_S2;
        let period_s = self.core.sample_period_s();
        let accel_g = m.accel_m_s2 / g0;
        let f32s = |v: imu_model::nalgebra::Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        let gains = self.core.scenario().device.gain_scale;
        let raw = |v: imu_model::nalgebra::Vector3<f64>, gain: u16| {
            [v.x, v.y, v.z].map(|x| f32::from(scale::units_to_raw_bits(x, gain).counts))
        };
        let temperature = self.temperature_stats(m.conditions.temp_c);
        let gps_time = self.gps_time(t_s, device_time_s);
        let mut d = ImuData::default();
        for f in &self.format.fields {
            match f.descriptor {
                field::RAW_ACCEL => d.raw_accel = Some(raw(accel_g, gains.accel)),
                field::RAW_GYRO => d.raw_gyro = Some(raw(m.gyro_rad_s, gains.gyro)),
                field::RAW_MAG => d.raw_mag = Some(raw(m.mag_gauss, gains.mag)),
                field::SCALED_ACCEL => d.accel_g = Some(f32s(accel_g)),
                field::SCALED_GYRO => d.gyro_rad_s = Some(f32s(m.gyro_rad_s)),
                field::SCALED_MAG => d.mag_gauss = Some(f32s(m.mag_gauss)),
                field::DELTA_THETA => d.delta_theta_rad = Some(f32s(m.gyro_rad_s * period_s)),
                field::DELTA_VELOCITY => d.delta_velocity_g_s = Some(f32s(accel_g * period_s)),
                field::INTERNAL_TIMESTAMP => d.internal_ticks = Some(ticks as u32),
                field::GPS_TIMESTAMP => d.gps_time = Some(gps_time),
                field::TEMPERATURE_ABS => d.temperature = Some(temperature),
                field::REFERENCE_TIME => {
                    d.reference_time_ns = Some((device_time_s * 1e9).floor().max(0.0) as u64);
                }
                _ => {}
            }
        }
        d
    }

    /// The GPS timestamp of a sample at scenario time `t_s`, device time `device_time_s`.
    fn gps_time(&self, t_s: f64, device_time_s: f64) -> GpsTime {
        let Some(g) = self.core.gnss_time(t_s) else {
            return GpsTime {
                tow_s: device_time_s % GPS_WEEK_S,
                week: (device_time_s / GPS_WEEK_S) as u16,
                valid_flags: 0,
            };
        };
        let gps_ns = gnss_time::unix_ns_to_gps_ns(g.utc_ns);
        let week_ns = gnss_time::SECONDS_PER_WEEK as u64 * 1_000_000_000;
        GpsTime {
            tow_s: (gps_ns % week_ns) as f64 * 1e-9,
            week: (gps_ns / week_ns) as u16,
            valid_flags: if g.valid { GPS_TOW_AND_WEEK_VALID } else { 0 },
        }
    }

    /// Min, max and mean of the temperature over the samples so far, this one included.
    fn temperature_stats(&mut self, temp_c: f64) -> TemperatureStats {
        let t = temp_c as f32;
        let (stats, n) = self.temperature.get_or_insert((
            TemperatureStats {
                min_c: t,
                max_c: t,
                mean_c: 0.0,
            },
            0,
        ));
        *n += 1;
        stats.min_c = stats.min_c.min(t);
        stats.max_c = stats.max_c.max(t);
        stats.mean_c += (t - stats.mean_c) / *n as f32;
        *stats
    }
}

/// Base rate / data rate (validated to be whole for a MIP scenario).
fn decimation_for(rate_hz: f64) -> u16 {
    (MIP_IMU_BASE_RATE_HZ / rate_hz).round() as u16
}

/// The power-on IMU message format: scaled accel, gyro, mag and the reference time, and the
/// GPS timestamp on a unit with GNSS time.
fn default_format(decimation: u16, gnss_time: bool) -> MessageFormat {
    let mut fields = vec![
        field::SCALED_ACCEL,
        field::SCALED_GYRO,
        field::SCALED_MAG,
        field::REFERENCE_TIME,
    ];
    if gnss_time {
        fields.push(field::GPS_TIMESTAMP);
    }
    MessageFormat {
        fields: fields
            .into_iter()
            .map(|descriptor| DescriptorRate {
                descriptor,
                decimation,
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use imu_model::Calibration;
    use imu_proto::mip::command::base;
    use imu_proto::mip::descriptor_set::BASE_COMMAND;

    use super::*;
    use crate::Scenario;

    fn device(rate_hz: f64) -> MipDevice {
        let text = format!(
            "name = \"mip-unit\"\nrate-hz = {rate_hz:?}\n[device]\nprotocol = \"mip\"\nserial-number = 77\n\
             firmware = 1234\n[[segment]]\nkind = \"static\"\nduration-s = 1.0\n"
        );
        let scenario = Scenario::from_toml_str(&text, "mip-unit.toml").unwrap();
        MipDevice::new(DeviceCore::new(scenario, Calibration::identity(), 1))
    }

    /// Sends `cmd` as the host would and returns the device's single reply.
    fn ask(d: &mut MipDevice, cmd: &MipCommand) -> MipReply {
        d.push(cmd.to_packet().as_bytes());
        let request = d.next_request().expect("a request").expect("a command");
        assert!(d.next_request().is_none());
        let packet = Packet::parse(d.handle(request).as_bytes()).unwrap();
        let mut replies = MipReply::decode_packet(&packet).unwrap();
        assert_eq!(replies.len(), 1);
        replies.remove(0)
    }

    #[test]
    fn a_unit_saved_streaming_streams_from_power_up_and_idles_on_command() {
        let text = "name = \"saved\"\nrate-hz = 100.0\n[device]\nprotocol = \"mip\"\n\
                    power-up-streaming = true\n[[segment]]\nkind = \"static\"\nduration-s = 1.0\n";
        let scenario = Scenario::from_toml_str(text, "saved.toml").unwrap();
        let mut d = MipDevice::new(DeviceCore::new(scenario, Calibration::identity(), 1));
        assert!(d.is_streaming(), "streams with no command");
        let (packet, _) = d.data_packet(0.01);
        let data = ImuData::decode_packet(&packet).unwrap();
        assert!(data.accel_g.is_some() && data.reference_time_ns.is_some());
        assert_eq!(ask(&mut d, &MipCommand::SetToIdle).code, AckCode::Ok);
        assert!(!d.is_streaming());
    }

    #[test]
    fn a_unit_with_gnss_time_sends_the_true_utc_and_drops_the_flags_in_an_outage() {
        let text = "name = \"gnss\"\nrate-hz = 100.0\n[device]\nprotocol = \"mip\"\n\
                    power-up-streaming = true\nclock-drift-ppm = 200.0\ngnss-time = true\n\
                    gnss-epoch-utc-s = 1767225600.0\n\
                    [[device.gnss-outage]]\nstart-s = 1.0\nend-s = 3.0\n\
                    [[segment]]\nkind = \"static\"\nduration-s = 5.0\n";
        let scenario = Scenario::from_toml_str(text, "gnss.toml").unwrap();
        let mut d = MipDevice::new(DeviceCore::new(scenario, Calibration::identity(), 1));
        let mut gnss_at = |t_s: f64| {
            let (packet, truth) = d.data_packet(t_s);
            assert_eq!(truth.t_s, t_s);
            let g = ImuData::decode_packet(&packet).unwrap().gps_time.unwrap();
            let utc_ns = gnss_time::gps_week_tow_to_unix_ns(u32::from(g.week), g.tow_s).unwrap();
            (utc_ns - 1_767_225_600_000_000_000, g.valid_flags)
        };
        // Valid: the true time, to the ns.
        assert_eq!(gnss_at(0.5), (500_000_000, GPS_TOW_AND_WEEK_VALID));
        // In the outage: not valid, propagated on the 200 ppm fast clock from the last fix
        // (the outage's start, 1 s): 1.99 s later it is 398 us ahead.
        let (ns, flags) = gnss_at(0.99);
        assert_eq!((ns, flags), (990_000_000, GPS_TOW_AND_WEEK_VALID));
        let (ns, flags) = gnss_at(2.99);
        assert_eq!(flags, 0);
        assert!((ns - 2_990_398_000).abs() <= 1, "{ns}");
        assert_eq!(gnss_at(3.0), (3_000_000_000, GPS_TOW_AND_WEEK_VALID));
    }

    #[test]
    fn identify_configure_and_resume() {
        let mut d = device(250.0);
        assert!(!d.is_streaming(), "powers up idle");
        assert_eq!(ask(&mut d, &MipCommand::Ping).code, AckCode::Ok);
        let info = ask(&mut d, &MipCommand::GetDeviceInfo);
        let Some(Response::DeviceInfo(info)) = info.response else {
            panic!("{info:?}")
        };
        assert_eq!(
            (info.serial_number.as_str(), info.firmware_version),
            ("77", 1234)
        );
        let rate = ask(&mut d, &MipCommand::GetImuBaseRate).response;
        assert_eq!(rate, Some(Response::ImuBaseRate { rate_hz: 1000 }));
        let format = MessageFormat {
            fields: [
                field::SCALED_ACCEL,
                field::DELTA_THETA,
                field::INTERNAL_TIMESTAMP,
            ]
            .map(|descriptor| DescriptorRate {
                descriptor,
                decimation: 4,
            })
            .to_vec(),
        };
        let write = MipCommand::ImuMessageFormat(Setting::Write(format.clone()));
        assert_eq!(ask(&mut d, &write).code, AckCode::Ok);
        let read = ask(&mut d, &MipCommand::ImuMessageFormat(Setting::Read));
        assert_eq!(read.response, Some(Response::ImuMessageFormat(format)));
        assert_eq!(ask(&mut d, &MipCommand::Resume).code, AckCode::Ok);
        assert!(d.is_streaming());
        let (packet, truth) = d.data_packet(0.5);
        let data = ImuData::decode_packet(&packet).unwrap();
        // Level and still: -1 g on z (x north, z down), within f32 rounding.
        let a = data.accel_g.unwrap();
        let g0 = imu_model::units::STANDARD_GRAVITY_M_S2;
        for (k, v) in a.iter().enumerate() {
            let expected = truth.measured_accel_m_s2[k] / g0;
            assert!((f64::from(*v) - expected).abs() <= 1e-7 * (1.0 + expected.abs()));
        }
        assert!((f64::from(a[2]) + 1.0).abs() < 1e-3, "{a:?}");
        assert_eq!(data.gyro_rad_s, None, "only the configured fields");
        let dtheta = data.delta_theta_rad.unwrap();
        for (k, v) in dtheta.iter().enumerate() {
            let expected = truth.measured_gyro_rad_s[k] / 250.0;
            assert!((f64::from(*v) - expected).abs() <= 1e-6 * expected.abs() + 1e-12);
        }
        assert_eq!(
            u64::from(data.internal_ticks.unwrap()),
            truth.ticks_unwrapped,
            "the truth is keyed by the internal timestamp"
        );
        assert_eq!(truth.command, IMU_DATA);
        assert_eq!(ask(&mut d, &MipCommand::SetToIdle).code, AckCode::Ok);
        assert!(!d.is_streaming());
    }

    #[test]
    fn generic_base_rate_and_message_format_of_the_imu_set() {
        let mut d = device(500.0);
        let r = ask(
            &mut d,
            &MipCommand::GetBaseRate {
                descriptor_set: 0x80,
            },
        );
        assert_eq!(
            r.response,
            Some(Response::BaseRate {
                descriptor_set: 0x80,
                rate_hz: 1000
            })
        );
        let format = MessageFormat {
            fields: vec![DescriptorRate {
                descriptor: field::SCALED_GYRO,
                decimation: 2,
            }],
        };
        let write = MipCommand::MessageFormat {
            descriptor_set: 0x80,
            setting: Setting::Write(format.clone()),
        };
        assert_eq!(ask(&mut d, &write).code, AckCode::Ok);
        let read = MipCommand::MessageFormat {
            descriptor_set: 0x80,
            setting: Setting::Read,
        };
        assert_eq!(
            ask(&mut d, &read).response,
            Some(Response::MessageFormat {
                descriptor_set: 0x80,
                format: format.clone()
            })
        );
        // The legacy read gives the same format.
        let legacy = ask(&mut d, &MipCommand::ImuMessageFormat(Setting::Read));
        assert_eq!(legacy.response, Some(Response::ImuMessageFormat(format)));
        let other = MipCommand::GetBaseRate {
            descriptor_set: 0x82,
        };
        assert_eq!(ask(&mut d, &other).code, AckCode::InvalidParameter);
    }

    #[test]
    fn unusable_requests_are_nacked_and_change_nothing() {
        let mut d = device(100.0);
        let before = d.format().clone();
        let wrong_rate = MessageFormat {
            fields: vec![DescriptorRate {
                descriptor: field::SCALED_ACCEL,
                decimation: 1,
            }],
        };
        let r = ask(
            &mut d,
            &MipCommand::ImuMessageFormat(Setting::Write(wrong_rate)),
        );
        assert_eq!(r.code, AckCode::InvalidParameter);
        let unknown_field = MessageFormat {
            fields: vec![DescriptorRate {
                descriptor: 0x0A,
                decimation: 10,
            }],
        };
        let r = ask(
            &mut d,
            &MipCommand::ImuMessageFormat(Setting::Write(unknown_field)),
        );
        assert_eq!(r.code, AckCode::InvalidParameter);
        assert_eq!(d.format(), &before);
        let other_set = MipCommand::DataStream {
            descriptor_set: 0x82,
            setting: Setting::Write(true),
        };
        assert_eq!(ask(&mut d, &other_set).code, AckCode::InvalidParameter);
        // A base-set command this unit does not know (comm speed 0x09).
        let mut b = imu_proto::mip::PacketBuilder::new(BASE_COMMAND);
        b.field(0x09, &[0x02, 0x01]).unwrap();
        d.push(b.build().as_bytes());
        let request = d.next_request().unwrap().unwrap();
        let reply = MipReply::decode_packet(&d.handle(request)).unwrap();
        assert_eq!(
            reply,
            [MipReply::ack((BASE_COMMAND, 0x09), AckCode::UnknownCommand)]
        );
        // Garbage before a command is rejected, the command still answered.
        d.push(&[0x00, 0x75, 0x13]);
        d.push(MipCommand::Ping.to_packet().as_bytes());
        assert_eq!(d.next_request(), Some(Err(3)));
        let Some(Ok(request)) = d.next_request() else {
            panic!("ping lost")
        };
        let reply = MipReply::decode_packet(&d.handle(request)).unwrap();
        assert_eq!(
            reply,
            [MipReply::ack((BASE_COMMAND, base::PING), AckCode::Ok)]
        );
    }

    #[test]
    fn same_scenario_and_seed_give_the_gx1_s_measurements() {
        let text = "name = \"same\"\nrate-hz = 200.0\n[[segment]]\nkind = \"rotate\"\naxis = \"x\"\n\
                    angle-deg = 90.0\nduration-s = 2.0\n";
        let scenario = Scenario::from_toml_str(text, "same.toml").unwrap();
        let mut truth_model = Calibration::identity();
        truth_model.accel.noise = Some(imu_model::NoiseModel {
            white_density: [0.003; 3],
            ..Default::default()
        });
        let mut gx1 = DeviceCore::new(scenario.clone(), truth_model.clone(), 9);
        let mut mip = MipDevice::new(DeviceCore::new(scenario, truth_model, 9));
        for k in 0..300 {
            let t_s = k as f64 / 200.0;
            let (_, a) = gx1.data_reply(imu_proto::Command::RawSensorBits, t_s);
            let (_, b) = mip.data_packet(t_s);
            assert_eq!(a.measured_accel_m_s2, b.measured_accel_m_s2, "sample {k}");
            assert_eq!(a.measured_gyro_rad_s, b.measured_gyro_rad_s);
            assert_eq!((a.seq, a.segment, a.t_s), (b.seq, b.segment, b.t_s));
        }
    }
}
