//! The virtual device speaking Xsens Xbus (as an MTi-630 would), sans-IO: the same physics,
//! truth model, noise and truth records as the 3DM-GX1 ([`DeviceCore`]), behind the Xsens
//! codec of `imu_proto::xsens`, used here the other way round from the host.
//!
//! What a host can rely on:
//! - The unit powers up in measurement mode streaming its default output, as real MTi units
//!   do: [`DEFAULT_OUTPUTS`] (packet counter, sample time fine, the compensated acceleration,
//!   rate of turn and magnetic field, the status word) as float32 at the scenario's rate. (A
//!   real unit's default adds the orientation quaternion, which this unit cannot make.)
//! - `GoToConfig` stops the stream and is acknowledged; `GoToMeasurement` starts it again;
//!   `WakeUpAck` enters config mode silently. `ReqDID` gives the scenario's serial number,
//!   `ReqProductCode` [`PRODUCT_CODE`], `ReqFWRev` the scenario's firmware word N as
//!   N/1000 . (N%1000)/100 . N%100.
//! - `SetOutputConfiguration` (config mode only) takes the outputs this unit can make
//!   ([`SUPPORTED`]), every float one in the same number format, each at the scenario's rate
//!   or at 0xFFFF / 0 ("every sample"); it is answered with the configuration in force. Anything
//!   else (another rate, an unknown output, mixed formats, config mode not entered) is
//!   answered with an `Error` message (33 invalid parameter, or 4 message invalid) and changes
//!   nothing. A reset acknowledges, keeps the configuration (the real unit stores it) and
//!   returns to measurement mode. Unknown messages get error 4.
//! - Readings: `AccelerationHR`/`RateOfTurnHR` are the measured values (truth model + noise),
//!   the raw reading a calibration corrects; `Acceleration`/`RateOfTurn`/`MagneticField` are
//!   the unit's own compensation, modelled as the truth model inverted exactly (what is left
//!   is the noise); delta v and delta q are the measured acceleration and rate over one sample
//!   period; the temperature is the true one; the UTC time is the scenario's GNSS time when it
//!   gives the unit one (`device.gnss-time`: valid outside its outages, propagated on the
//!   drifting clock inside them), else the true time [`SIM_UTC_EPOCH_NS`] + scenario time,
//!   flagged valid (the unit's GNSS receiver has a fix).
//! - `SampleTimeFine` follows the device's own oscillator (the scenario's clock drift): 10 kHz
//!   counts since power-on, u32 on the wire. The truth record's `ticks_unwrapped` is that
//!   count unwrapped and its `command` is the MTData2 message id, 0x36.

use std::collections::VecDeque;

use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::gnss_time::unix_ns_to_utc_fields;
use imu_proto::xsens::data::{UTC_VALID, id};
use imu_proto::xsens::{
    DataId, FirmwareRev, Format, Message, MtData2, OutputConfiguration, OutputSetting,
    SAMPLE_TIME_FINE_HZ, UtcTime, XsensCommand, XsensDecoder, XsensError, XsensEvent, XsensReply,
    mid,
};
use imu_rec::truth::TruthSample;

use crate::device::{DeviceCore, Measurement};

/// What `ReqProductCode` answers.
pub const PRODUCT_CODE: &str = "MTi-630-SIM";

/// UTC at scenario time 0: 2026-01-01T00:00:00Z, Unix ns.
pub const SIM_UTC_EPOCH_NS: i64 = 1_767_225_600_000_000_000;

/// Error code: the message is invalid or not implemented (`mtdef.py`).
pub const ERROR_INVALID_MESSAGE: u8 = 4;
/// Error code: an invalid parameter.
pub const ERROR_INVALID_PARAMETER: u8 = 33;

/// Outputs (data ids without format and frame bits) the simulated unit can make.
pub const SUPPORTED: [u16; 12] = [
    id::PACKET_COUNTER,
    id::SAMPLE_TIME_FINE,
    id::UTC_TIME,
    id::TEMPERATURE,
    id::DELTA_V,
    id::ACCELERATION,
    id::ACCELERATION_HR,
    id::RATE_OF_TURN,
    id::DELTA_Q,
    id::RATE_OF_TURN_HR,
    id::MAGNETIC_FIELD,
    id::STATUS_WORD,
];

/// The power-up outputs (float32), each at the scenario's rate.
pub const DEFAULT_OUTPUTS: [u16; 6] = [
    id::PACKET_COUNTER,
    id::SAMPLE_TIME_FINE,
    id::ACCELERATION,
    id::RATE_OF_TURN,
    id::MAGNETIC_FIELD,
    id::STATUS_WORD,
];

/// Ids whose items carry no float, so their format bits mean nothing.
const NOT_FLOAT: [u16; 4] = [
    id::PACKET_COUNTER,
    id::SAMPLE_TIME_FINE,
    id::UTC_TIME,
    id::STATUS_WORD,
];

/// Rate values meaning "with every sample".
const EVERY_SAMPLE: [u16; 2] = [0, 0xFFFF];

/// One message from the host: its id and the command, or why it was not understood.
#[derive(Debug, Clone, PartialEq)]
pub struct XsensRequest {
    mid: u8,
    command: Result<XsensCommand, XsensError>,
}

impl XsensRequest {
    /// The message id the host sent.
    pub fn mid(&self) -> u8 {
        self.mid
    }
}

/// The sans-IO Xsens device.
pub struct XsensDevice {
    core: DeviceCore,
    decoder: XsensDecoder,
    requests: VecDeque<XsensRequest>,
    outputs: OutputConfiguration,
    config_mode: bool,
    packet_counter: u16,
}

impl XsensDevice {
    /// A powered-on unit around the physics of `core`, in measurement mode streaming its
    /// default outputs.
    pub fn new(core: DeviceCore) -> Self {
        let rate_hz = rate_word(core.scenario().rate_hz);
        Self {
            core,
            decoder: XsensDecoder::new(),
            requests: VecDeque::new(),
            outputs: default_outputs(rate_hz),
            config_mode: false,
            packet_counter: 0,
        }
    }

    /// The physics and truth behind the unit.
    pub fn core(&self) -> &DeviceCore {
        &self.core
    }

    /// The output configuration in force.
    pub fn outputs(&self) -> &OutputConfiguration {
        &self.outputs
    }

    /// True while the unit sends data on its own.
    pub fn is_streaming(&self) -> bool {
        !self.config_mode && !self.outputs.0.is_empty()
    }

    /// Bytes from the host.
    pub fn push(&mut self, bytes: &[u8]) {
        self.decoder.push(bytes);
    }

    /// Host bytes not yet part of a message or a rejected run.
    pub fn pending_len(&self) -> usize {
        self.decoder.pending_len()
    }

    /// The host stopped sending inside a message: report what is pending (the next
    /// [`next_request`](Self::next_request) calls give it back as rejected bytes).
    pub fn expire_partial(&mut self) {
        self.decoder.flush();
    }

    /// The link was replugged: what was half received is gone.
    pub fn reset_link(&mut self) {
        self.decoder = XsensDecoder::new();
        self.requests.clear();
    }

    /// The next message from the host, or `Err(n)` for `n` rejected bytes.
    pub fn next_request(&mut self) -> Option<Result<XsensRequest, u64>> {
        loop {
            if let Some(r) = self.requests.pop_front() {
                return Some(Ok(r));
            }
            match self.decoder.next_event()? {
                XsensEvent::Rejected { bytes, .. } => return Some(Err(bytes.len() as u64)),
                XsensEvent::Packet { packet, .. } => self.requests.push_back(XsensRequest {
                    mid: packet.mid(),
                    command: XsensCommand::decode(&packet),
                }),
            }
        }
    }

    /// Answers one message: the reply, if the message has one.
    pub fn handle(&mut self, request: XsensRequest) -> Option<Message> {
        let reply = match request.command {
            Ok(cmd) => self.handle_command(cmd)?,
            Err(XsensError::UnknownMessage(_)) => XsensReply::Error(ERROR_INVALID_MESSAGE),
            Err(_) => XsensReply::Error(ERROR_INVALID_PARAMETER),
        };
        Some(reply.to_message())
    }

    fn handle_command(&mut self, cmd: XsensCommand) -> Option<XsensReply> {
        let d = &self.core.scenario().device;
        Some(match cmd {
            XsensCommand::WakeUpAck => {
                self.config_mode = true;
                return None;
            }
            XsensCommand::GoToConfig => {
                self.config_mode = true;
                XsensReply::GoToConfigAck
            }
            XsensCommand::GoToMeasurement => {
                self.config_mode = false;
                XsensReply::GoToMeasurementAck
            }
            XsensCommand::ReqDeviceId => XsensReply::DeviceId(u64::from(d.serial_number)),
            XsensCommand::ReqProductCode => XsensReply::ProductCode(PRODUCT_CODE.into()),
            XsensCommand::ReqFirmwareRev => XsensReply::FirmwareRev(FirmwareRev {
                major: (d.firmware / 1000) as u8,
                minor: ((d.firmware % 1000) / 100) as u8,
                revision: (d.firmware % 100) as u8,
                build: None,
            }),
            XsensCommand::ReqOutputConfiguration => {
                XsensReply::OutputConfiguration(self.outputs.clone())
            }
            XsensCommand::SetOutputConfiguration(config) => {
                if !self.config_mode {
                    return Some(XsensReply::Error(ERROR_INVALID_MESSAGE));
                }
                if !self.usable(&config) {
                    return Some(XsensReply::Error(ERROR_INVALID_PARAMETER));
                }
                self.outputs = config;
                XsensReply::OutputConfiguration(self.outputs.clone())
            }
            XsensCommand::Reset => {
                self.config_mode = false;
                self.packet_counter = 0;
                XsensReply::ResetAck
            }
        })
    }

    /// Every output is one this unit makes, at its one rate, floats in one format.
    fn usable(&self, config: &OutputConfiguration) -> bool {
        let rate = rate_word(self.core.scenario().rate_hz);
        let mut format = None;
        config.0.iter().all(|s| {
            let id = DataId(s.data_id);
            let rate_ok = s.rate_hz == rate || EVERY_SAMPLE.contains(&s.rate_hz);
            let format_ok =
                NOT_FLOAT.contains(&id.base()) || *format.get_or_insert(id.format()) == id.format();
            SUPPORTED.contains(&id.base()) && rate_ok && format_ok
        })
    }

    /// The number format of the configured float outputs.
    fn format(&self) -> Format {
        self.outputs
            .0
            .iter()
            .map(|s| DataId(s.data_id))
            .find(|id| !NOT_FLOAT.contains(&id.base()))
            .map_or(Format::Float32, DataId::format)
    }

    /// The data message due at scenario time `t_s`, with its truth record.
    pub fn data_message(&mut self, t_s: f64) -> (Message, TruthSample) {
        let m = self.core.measure(t_s, true);
        let device_time_s = self.core.device_time_s(t_s);
        let ticks = (device_time_s * f64::from(SAMPLE_TIME_FINE_HZ))
            .floor()
            .max(0.0) as u64;
        let data = self.mt_data2(&m, t_s, ticks);
        self.packet_counter = self.packet_counter.wrapping_add(1);
        let truth = self.core.truth_sample(&m, mid::MT_DATA2, ticks, false);
        (data.to_message(self.format()), truth)
    }

    /// The configured items, made from `m`.
    fn mt_data2(&self, m: &Measurement, t_s: f64, ticks: u64) -> MtData2 {
        let period_s = self.core.sample_period_s();
        let arr = |v: Vector3<f64>| [v.x, v.y, v.z];
        let compensated = self.compensated(m);
        let mut d = MtData2::default();
        for s in &self.outputs.0 {
            match DataId(s.data_id).base() {
                id::PACKET_COUNTER => d.packet_counter = Some(self.packet_counter),
                id::SAMPLE_TIME_FINE => d.sample_time_fine = Some(ticks as u32),
                id::UTC_TIME => d.utc = Some(utc_time_at(&self.core, t_s)),
                id::TEMPERATURE => d.temperature_c = Some(m.conditions.temp_c),
                id::DELTA_V => d.delta_v_m_s = Some(arr(m.accel_m_s2 * period_s)),
                id::ACCELERATION => d.acceleration_m_s2 = Some(arr(compensated.accel_m_s2)),
                id::ACCELERATION_HR => d.acceleration_hr_m_s2 = Some(arr(m.accel_m_s2)),
                id::RATE_OF_TURN => d.rate_of_turn_rad_s = Some(arr(compensated.gyro_rad_s)),
                id::DELTA_Q => d.delta_q = Some(delta_q(m.gyro_rad_s * period_s)),
                id::RATE_OF_TURN_HR => d.rate_of_turn_hr_rad_s = Some(arr(m.gyro_rad_s)),
                // The simulated unit's calibration field is taken as 1 gauss, so its
                // normalised field is its field in gauss.
                id::MAGNETIC_FIELD => {
                    d.magnetic_field_normalised = Some(arr(compensated.mag_gauss))
                }
                id::STATUS_WORD => d.status_word = Some(0),
                _ => {}
            }
        }
        d
    }

    /// The unit's own compensation: the truth model inverted (its factory calibration and
    /// bias estimates are exact), leaving the noise.
    fn compensated(&self, m: &Measurement) -> Measured {
        let measured = Measured {
            accel_m_s2: m.accel_m_s2,
            gyro_rad_s: m.gyro_rad_s,
            mag_gauss: m.mag_gauss,
        };
        let c = self.core.truth_model().correct(
            &measured,
            m.conditions.temp_c,
            m.conditions.time_since_power_on_s,
            m.state.angular_accel_rad_s2,
        );
        Measured {
            accel_m_s2: c.accel_m_s2,
            gyro_rad_s: c.gyro_rad_s,
            mag_gauss: c.mag_gauss,
        }
    }
}

/// The UTC time field at scenario time `t_s`: the scenario's GNSS time
/// (`DeviceCore::gnss_time`: valid outside its outages) if it gives the unit one, else the true
/// time from [`SIM_UTC_EPOCH_NS`], valid.
fn utc_time_at(core: &DeviceCore, t_s: f64) -> UtcTime {
    let (utc_ns, valid) = core
        .gnss_time(t_s)
        .map_or((SIM_UTC_EPOCH_NS + (t_s * 1e9).round() as i64, true), |g| {
            (g.utc_ns, g.valid)
        });
    let (year, month, day, hour, minute, second, ns) = unix_ns_to_utc_fields(utc_ns);
    UtcTime {
        ns,
        year,
        month,
        day,
        hour,
        minute,
        second,
        flags: if valid { UTC_VALID } else { 0 },
    }
}

/// The unit quaternion (w, x, y, z) of rotation vector `theta_rad`.
fn delta_q(theta_rad: Vector3<f64>) -> [f64; 4] {
    let angle = theta_rad.norm();
    if angle == 0.0 {
        return [1.0, 0.0, 0.0, 0.0];
    }
    let axis = theta_rad / angle;
    let (s, c) = (angle / 2.0).sin_cos();
    [c, axis.x * s, axis.y * s, axis.z * s]
}

/// The scenario rate as an output-configuration rate word (validated to be whole Hz up to
/// [`crate::scenario::XSENS_MAX_RATE_HZ`]).
fn rate_word(rate_hz: f64) -> u16 {
    rate_hz.round() as u16
}

/// The power-up output configuration at `rate_hz`.
fn default_outputs(rate_hz: u16) -> OutputConfiguration {
    OutputConfiguration(
        DEFAULT_OUTPUTS
            .iter()
            .map(|&data_id| OutputSetting { data_id, rate_hz })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use imu_model::Calibration;

    use super::*;
    use crate::Scenario;

    fn device(rate_hz: f64, drift_ppm: f64) -> XsensDevice {
        let text = format!(
            "name = \"mti\"\nrate-hz = {rate_hz:?}\n[device]\nprotocol = \"xsens\"\nserial-number = 77\n\
             firmware = 1234\nclock-drift-ppm = {drift_ppm:?}\n[[segment]]\nkind = \"static\"\nduration-s = 1.0\n"
        );
        let scenario = Scenario::from_toml_str(&text, "mti.toml").unwrap();
        XsensDevice::new(DeviceCore::new(scenario, Calibration::identity(), 1))
    }

    /// Sends `cmd` as the host would and returns the device's reply, if any.
    fn ask(d: &mut XsensDevice, cmd: &XsensCommand) -> Option<XsensReply> {
        d.push(cmd.to_message().as_bytes());
        let request = d.next_request().expect("a request").expect("a message");
        assert!(d.next_request().is_none());
        let msg = d.handle(request)?;
        Some(XsensReply::decode(&Message::parse(msg.as_bytes()).unwrap()).unwrap())
    }

    #[test]
    fn powers_up_streaming_its_default_outputs() {
        let mut d = device(100.0, 0.0);
        assert!(d.is_streaming(), "streams with no command");
        let (msg, truth) = d.data_message(0.5);
        let data = MtData2::decode(&msg).unwrap();
        assert_eq!(data.packet_counter, Some(0));
        assert!(data.acceleration_m_s2.is_some() && data.magnetic_field_normalised.is_some());
        assert_eq!(data.acceleration_hr_m_s2, None);
        assert_eq!(
            u64::from(data.sample_time_fine.unwrap()),
            truth.ticks_unwrapped
        );
        assert_eq!(truth.command, mid::MT_DATA2);
        let (msg, _) = d.data_message(0.51);
        assert_eq!(MtData2::decode(&msg).unwrap().packet_counter, Some(1));
    }

    #[test]
    fn identify_configure_read_back_and_measure() {
        let mut d = device(400.0, 0.0);
        assert_eq!(
            ask(&mut d, &XsensCommand::GoToConfig),
            Some(XsensReply::GoToConfigAck)
        );
        assert!(!d.is_streaming());
        assert_eq!(
            ask(&mut d, &XsensCommand::ReqDeviceId),
            Some(XsensReply::DeviceId(77))
        );
        assert_eq!(
            ask(&mut d, &XsensCommand::ReqProductCode),
            Some(XsensReply::ProductCode(PRODUCT_CODE.into()))
        );
        let Some(XsensReply::FirmwareRev(fw)) = ask(&mut d, &XsensCommand::ReqFirmwareRev) else {
            panic!("no firmware revision")
        };
        assert_eq!(fw.to_string(), "1.2.34");
        let config = OutputConfiguration(
            [
                (id::SAMPLE_TIME_FINE, 0xFFFF),
                (id::UTC_TIME, 400),
                (
                    DataId::with_format(id::ACCELERATION_HR, Format::Fp1632).0,
                    400,
                ),
                (
                    DataId::with_format(id::RATE_OF_TURN_HR, Format::Fp1632).0,
                    400,
                ),
                (DataId::with_format(id::TEMPERATURE, Format::Fp1632).0, 400),
            ]
            .map(|(data_id, rate_hz)| OutputSetting { data_id, rate_hz })
            .to_vec(),
        );
        assert_eq!(
            ask(
                &mut d,
                &XsensCommand::SetOutputConfiguration(config.clone())
            ),
            Some(XsensReply::OutputConfiguration(config.clone()))
        );
        assert_eq!(
            ask(&mut d, &XsensCommand::ReqOutputConfiguration),
            Some(XsensReply::OutputConfiguration(config))
        );
        assert_eq!(
            ask(&mut d, &XsensCommand::GoToMeasurement),
            Some(XsensReply::GoToMeasurementAck)
        );
        assert!(d.is_streaming());
        let (msg, truth) = d.data_message(0.25);
        let data = MtData2::decode(&msg).unwrap();
        // fp16.32 carries the measured values to 2^-33.
        let a = data.acceleration_hr_m_s2.unwrap();
        for (v, m) in a.iter().zip(truth.measured_accel_m_s2) {
            assert!((v - m).abs() <= 2f64.powi(-33));
        }
        // Level and still: -1 g on z (x north, z down).
        assert!(
            (a[2] + imu_model::units::STANDARD_GRAVITY_M_S2).abs() < 0.05,
            "{a:?}"
        );
        assert_eq!(data.acceleration_m_s2, None, "only the configured outputs");
        let utc = data.utc.unwrap();
        assert!(utc.valid());
        assert_eq!(utc.unix_ns(), Some(SIM_UTC_EPOCH_NS + 250_000_000));
        assert!((data.temperature_c.unwrap() - truth.temp_c).abs() < 1e-9);
    }

    #[test]
    fn unusable_configurations_are_errors_and_change_nothing() {
        let mut d = device(100.0, 0.0);
        let wrong_rate = OutputConfiguration(vec![OutputSetting {
            data_id: id::ACCELERATION_HR,
            rate_hz: 200,
        }]);
        let set = XsensCommand::SetOutputConfiguration(wrong_rate);
        // Not in config mode yet.
        assert_eq!(
            ask(&mut d, &set),
            Some(XsensReply::Error(ERROR_INVALID_MESSAGE))
        );
        assert_eq!(ask(&mut d, &XsensCommand::WakeUpAck), None);
        assert!(!d.is_streaming(), "WakeUpAck enters config mode");
        assert_eq!(
            ask(&mut d, &set),
            Some(XsensReply::Error(ERROR_INVALID_PARAMETER))
        );
        let mixed = OutputConfiguration(vec![
            OutputSetting {
                data_id: id::ACCELERATION_HR,
                rate_hz: 100,
            },
            OutputSetting {
                data_id: DataId::with_format(id::RATE_OF_TURN_HR, Format::Float64).0,
                rate_hz: 100,
            },
        ]);
        assert_eq!(
            ask(&mut d, &XsensCommand::SetOutputConfiguration(mixed)),
            Some(XsensReply::Error(ERROR_INVALID_PARAMETER))
        );
        assert_eq!(d.outputs(), &default_outputs(100));
        // An unknown message, and garbage before a good one.
        d.push(Message::new(0x99, &[]).unwrap().as_bytes());
        let request = d.next_request().unwrap().unwrap();
        assert_eq!(request.mid(), 0x99);
        assert_eq!(
            d.handle(request).map(|m| XsensReply::decode(&m).unwrap()),
            Some(XsensReply::Error(ERROR_INVALID_MESSAGE))
        );
        d.push(&[0x00, 0xFA, 0x13]);
        d.push(XsensCommand::Reset.to_message().as_bytes());
        assert_eq!(d.next_request(), Some(Err(3)));
        let request = d.next_request().unwrap().unwrap();
        assert_eq!(
            d.handle(request).map(|m| XsensReply::decode(&m).unwrap()),
            Some(XsensReply::ResetAck)
        );
        assert!(d.is_streaming(), "a reset returns to measurement mode");
    }

    #[test]
    fn sample_time_fine_follows_the_drifting_clock() {
        let mut d = device(100.0, 200.0);
        let (msg, _) = d.data_message(10.0);
        let stf = MtData2::decode(&msg).unwrap().sample_time_fine.unwrap();
        let device_s = d.core().device_time_s(10.0);
        assert_eq!(stf, (device_s * 10_000.0).floor() as u32);
        // 200 ppm fast: ahead of true time (since power-on) by 200e-6 of it, to a count.
        let true_s = 10.0 + d.core().scenario().power_on_before_s;
        let ahead = f64::from(stf) - true_s * 10_000.0;
        assert!((ahead - true_s * 200e-6 * 10_000.0).abs() <= 1.0, "{ahead}");
    }

    #[test]
    fn compensated_outputs_remove_the_truth_model() {
        let text = "name = \"c\"\nrate-hz = 100.0\n[device]\nprotocol = \"xsens\"\n\
                    [[segment]]\nkind = \"static\"\nduration-s = 1.0\n";
        let scenario = Scenario::from_toml_str(text, "c.toml").unwrap();
        let mut truth_model = Calibration::identity();
        truth_model.gyro.bias = Some(imu_model::effects::Bias {
            value: [0.01, -0.02, 0.03],
            std_error: None,
        });
        let mut d = XsensDevice::new(DeviceCore::new(scenario, truth_model, 1));
        let (msg, truth) = d.data_message(0.5);
        let data = MtData2::decode(&msg).unwrap();
        let w = data.rate_of_turn_rad_s.unwrap();
        for ((v, expected), measured) in w
            .iter()
            .zip(truth.angular_rate_rad_s)
            .zip(truth.measured_gyro_rad_s)
        {
            // float32 of the true rate (the measured one minus the bias).
            assert!((v - expected).abs() < 1e-6, "{w:?} vs {expected}");
            assert!((measured - expected).abs() > 5e-3);
        }
    }

    #[test]
    fn a_rate_an_mti_cannot_stream_is_a_scenario_error() {
        for rate in ["100.5", "2500.0"] {
            let text = format!(
                "name = \"r\"\nrate-hz = {rate}\n[device]\nprotocol = \"xsens\"\n\
                 [[segment]]\nkind = \"static\"\nduration-s = 1.0\n"
            );
            let e = Scenario::from_toml_str(&text, "r.toml")
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("not an Xsens output rate") && e.contains("r.toml"),
                "{e}"
            );
        }
    }
}
