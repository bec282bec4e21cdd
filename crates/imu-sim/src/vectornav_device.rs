//! The virtual device speaking VectorNav's protocol (as a VN-100 or VN-200 would), sans-IO: the
//! same physics, truth model, noise and truth records as the 3DM-GX1 ([`DeviceCore`]), behind
//! the codec of `imu_proto::vectornav`, used here the other way round from the host.
//!
//! What a host can rely on:
//! - The unit powers up streaming its ASCII asynchronous output, `$VNYPR` (register 6 = 1) at
//!   40 Hz (register 7), with every binary output off, as a factory-fresh unit does; so the
//!   scenario clock starts at power-up. Binary output 1 holds the default fields at the
//!   scenario's rate divisor (off), so a host keeping the unit's rate finds it there. With the scenario's `device.power-up-streaming` it
//!   powers up with the ASCII output off and binary output 1 streaming its default fields
//!   ([`default_fields`]) at the scenario's rate (a unit set up and saved so).
//! - It answers reads of registers 1 (model: the scenario's `device.model`, default
//!   [`DEFAULT_MODEL`]), 2, 3 (serial), 4 (firmware), 6, 7 and 75-77, and writes of 6, 7 and
//!   75-77, each with the reply a unit gives (the value echoed); anything else is a `$VNERR`:
//!   a bad check 3, an unknown command 4, an unknown register 8, a read-only register written
//!   9, a value it cannot apply 7. Sentences may carry the checksum, the CRC or `XX`; replies
//!   carry the checksum.
//! - Binary outputs stream only at the scenario's rate, so a rate divisor other than
//!   [`IMU_RATE_HZ`] / `rate-hz`, a field this unit cannot fill, or two outputs on at once is
//!   refused with error 7 and changes nothing. Register 6 takes 0 (off) or 1 (YPR).
//! - Messages carry the startup time in ns from the device's own oscillator (the scenario's
//!   clock drift), the uncompensated accel/gyro/mag (truth model + noise: the raw reading a
//!   calibration corrects), the compensated ones (the truth with the same noise: the unit's
//!   factory compensation modelled as removing the truth model's errors exactly), temperature,
//!   pressure (101.325 kPa), delta theta (degrees) and delta velocity over the sample period.
//!   A VN-200/300 model also sends GPS time: the scenario's GNSS time when it gives the unit
//!   one (`device.gnss-time`: time status valid outside its outages, propagated on the
//!   drifting clock inside them), else the true time from [`GPS_START_UNIX_NS`], valid; a
//!   VN-100 asked for GPS time sends 0 with the time status clear.
//! - The truth record's `ticks_unwrapped` is the startup time in ns and its `command` 0xFA.

use std::collections::VecDeque;

use imu_proto::gnss_time::unix_ns_to_gps_ns;
use imu_proto::vectornav::binary::{common, group, time};
use imu_proto::vectornav::{
    BinaryData, BinaryMessage, BinaryOutputConfig, Check, DeltaTheta, IMU_RATE_HZ, OutputFields,
    Register, SYNC, TimeStatus, VnCommand, VnDecoder, VnError, VnEvent, VnReply, error_code, reg,
};
use imu_rec::truth::TruthSample;

use crate::device::DeviceCore;

/// Model name reported when the scenario names none.
pub const DEFAULT_MODEL: &str = "VN-100T-CR";

/// Hardware revision reported in register 2.
pub const HARDWARE_REVISION: u32 = 2;

/// UTC the simulated GNSS time starts from at scenario time 0: 2026-01-01T00:00:00Z.
pub const GPS_START_UNIX_NS: i64 = 1_767_225_600_000_000_000;

/// ASCII output frequency at power-up, Hz.
pub const POWER_UP_ASYNC_HZ: u32 = 40;

/// Air pressure the unit reports, kPa.
const PRESSURE_KPA: f32 = 101.325;

/// Field bits the simulated unit fills, per group.
fn supported() -> OutputFields {
    let mut f = OutputFields::default();
    f.words[group::COMMON] = common::TIME_STARTUP
        | common::TIME_GPS
        | common::ANGULAR_RATE
        | common::ACCEL
        | common::IMU
        | common::MAG_PRES
        | common::DELTA_THETA_VEL;
    f.words[group::TIME] = time::TIME_STARTUP | time::TIME_GPS | time::TIME_STATUS;
    f.words[group::IMU] = 0x07FF;
    f
}

/// The fields of a saved binary output: the fields a calibration needs (imud's choice too).
pub use imu_proto::vectornav::calibration_fields as default_fields;

/// One sentence from the host: the command, or the `$VNERR` code it earns.
pub type VnRequest = Result<VnCommand, u8>;

/// The sans-IO VectorNav device.
pub struct VnDevice {
    core: DeviceCore,
    decoder: VnDecoder,
    requests: VecDeque<VnRequest>,
    model: String,
    async_type: u32,
    async_hz: u32,
    binary: [BinaryOutputConfig; 3],
    /// Samples streamed since the unit started streaming (paces the ASCII output).
    samples: u64,
}

impl VnDevice {
    /// A powered-on unit around the physics of `core` (see the module documentation).
    pub fn new(core: DeviceCore) -> Self {
        let d = &core.scenario().device;
        let model = if d.model.is_empty() {
            DEFAULT_MODEL.to_string()
        } else {
            d.model.clone()
        };
        let mut binary = [BinaryOutputConfig::default(); 3];
        // Binary output 1 holds the default fields at the scenario's rate, on only when the
        // unit was saved streaming.
        binary[0] = BinaryOutputConfig {
            async_mode: 0,
            rate_divisor: divisor_for(core.scenario().rate_hz),
            fields: default_fields(has_gnss(&model)),
        };
        let async_type = if d.power_up_streaming {
            binary[0].async_mode = 1;
            0
        } else {
            imu_proto::vectornav::ascii::ASYNC_YPR
        };
        Self {
            core,
            decoder: VnDecoder::new(),
            requests: VecDeque::new(),
            model,
            async_type,
            async_hz: POWER_UP_ASYNC_HZ,
            binary,
            samples: 0,
        }
    }

    /// The physics and truth behind the unit.
    pub fn core(&self) -> &DeviceCore {
        &self.core
    }

    /// The model name it reports.
    pub fn model(&self) -> &str {
        &self.model
    }

    /// The one rate divisor the unit streams binary outputs at.
    pub fn rate_divisor(&self) -> u16 {
        divisor_for(self.core.scenario().rate_hz)
    }

    /// The binary output streaming, if one is.
    pub fn active_output(&self) -> Option<&BinaryOutputConfig> {
        self.binary.iter().find(|b| b.async_mode != 0)
    }

    /// True while the unit sends anything on its own (ASCII or binary output).
    pub fn is_streaming(&self) -> bool {
        self.async_type != 0 || self.active_output().is_some()
    }

    /// Bytes from the host.
    pub fn push(&mut self, bytes: &[u8]) {
        self.decoder.push(bytes);
    }

    /// Host bytes not yet part of a sentence or a rejected run.
    pub fn pending_len(&self) -> usize {
        self.decoder.pending_len()
    }

    /// The host stopped inside a sentence: report what is pending.
    pub fn expire_partial(&mut self) {
        self.decoder.flush();
    }

    /// The link was replugged: what was half received is gone.
    pub fn reset_link(&mut self) {
        self.decoder = VnDecoder::new();
        self.requests.clear();
    }

    /// The next sentence from the host, or `Err(n)` for `n` rejected bytes (a sentence with a
    /// bad check is also answered, with error 3, as a unit does).
    pub fn next_request(&mut self) -> Option<Result<VnRequest, u64>> {
        if let Some(r) = self.requests.pop_front() {
            return Some(Ok(r));
        }
        Some(match self.decoder.next_event()? {
            VnEvent::Ascii { sentence, .. } => {
                Ok(VnCommand::decode(&sentence).map_err(|e| match e {
                    VnError::UnknownRegister(_) => error_code::INVALID_REGISTER,
                    VnError::UnknownHeader(_) => error_code::INVALID_COMMAND,
                    _ => error_code::INVALID_PARAMETER,
                }))
            }
            VnEvent::Rejected { bytes, .. } => {
                if bytes.first() == Some(&b'$')
                    && imu_proto::vectornav::Sentence::parse(&bytes)
                        .is_err_and(|e| matches!(e, VnError::BadChecksum { .. }))
                {
                    self.requests.push_back(Err(error_code::INVALID_CHECKSUM));
                }
                Err(bytes.len() as u64)
            }
            // A host sends no binary messages; one is not a command.
            VnEvent::Binary { message, .. } => Err(message.as_bytes().len() as u64),
        })
    }

    /// Answers one request: the reply sentence's bytes.
    pub fn handle(&mut self, request: VnRequest) -> Vec<u8> {
        let reply = match request {
            Ok(VnCommand::Read(id)) => self.read(id).map(VnReply::Read),
            Ok(VnCommand::Write(r)) => self.write(r).map(VnReply::Written),
            Err(code) => Err(code),
        };
        reply
            .unwrap_or_else(VnReply::Error)
            .to_sentence(Check::Checksum8)
            .as_bytes()
            .to_vec()
    }

    fn read(&self, id: u8) -> Result<Register, u8> {
        let d = &self.core.scenario().device;
        Ok(match id {
            reg::MODEL => Register::Model(self.model.clone()),
            reg::HARDWARE_REVISION => Register::HardwareRevision(HARDWARE_REVISION),
            reg::SERIAL_NUMBER => Register::SerialNumber(u32::from(d.serial_number)),
            reg::FIRMWARE => Register::Firmware(firmware_text(d.firmware)),
            reg::ASYNC_OUTPUT_TYPE => Register::AsyncOutputType(self.async_type),
            reg::ASYNC_OUTPUT_FREQUENCY => Register::AsyncOutputFrequency(self.async_hz),
            75..=77 => Register::BinaryOutput {
                index: id - 74,
                config: self.binary[usize::from(id - 75)],
            },
            _ => return Err(error_code::INVALID_REGISTER),
        })
    }

    fn write(&mut self, r: Register) -> Result<Register, u8> {
        match &r {
            Register::Model(_)
            | Register::HardwareRevision(_)
            | Register::SerialNumber(_)
            | Register::Firmware(_) => return Err(error_code::UNAUTHORIZED_ACCESS),
            Register::AsyncOutputType(t) => {
                if *t > imu_proto::vectornav::ascii::ASYNC_YPR {
                    return Err(error_code::INVALID_PARAMETER);
                }
                self.async_type = *t;
            }
            Register::AsyncOutputFrequency(hz) => {
                if ![1, 2, 4, 5, 10, 20, 25, 40, 50, 100, 200].contains(hz) {
                    return Err(error_code::INVALID_PARAMETER);
                }
                self.async_hz = *hz;
            }
            Register::BinaryOutput { index, config } => {
                let i = usize::from(index - 1);
                let others_on = (0..3).any(|j| j != i && self.binary[j].async_mode != 0);
                let usable = config.async_mode == 0
                    || (config.rate_divisor == self.rate_divisor()
                        && !others_on
                        && config.async_mode <= 3
                        && (0..group::COUNT)
                            .all(|g| config.fields.words[g] & !supported().words[g] == 0));
                if !usable {
                    return Err(error_code::INVALID_PARAMETER);
                }
                self.binary[i] = *config;
            }
        }
        Ok(r)
    }

    /// Appends what the unit sends at scenario time `t_s`: the binary message of the active
    /// output (and its truth record) and, when due, the ASCII output. `None` without a binary
    /// output.
    pub fn stream_sample(&mut self, t_s: f64, out: &mut Vec<u8>) -> Option<TruthSample> {
        let k = self.samples;
        self.samples += 1;
        if self.async_type != 0 {
            // The ASCII output at its own rate: one sentence whenever a period of it has passed.
            let rate_hz = self.core.scenario().rate_hz;
            let due = |k: u64| (k as f64 * f64::from(self.async_hz) / rate_hz).floor() as u64;
            if k == 0 || due(k) != due(k - 1) {
                out.extend_from_slice(self.ypr_sentence(t_s).as_bytes());
            }
        }
        let fields = self.active_output()?.fields;
        let (message, truth) = self.data_message(fields, t_s);
        out.extend_from_slice(message.as_bytes());
        Some(truth)
    }

    fn ypr_sentence(&self, t_s: f64) -> imu_proto::vectornav::Sentence {
        let state = self.core.timeline().state(t_s);
        let (roll, pitch, yaw) = self.core.ned_from_sensor(&state).euler_angles();
        let ypr = [yaw, pitch, roll].map(|a| a.to_degrees() as f32);
        VnReply::Ypr(ypr).to_sentence(Check::Checksum8)
    }

    /// The binary message of `fields` due at scenario time `t_s`, with its truth record.
    pub fn data_message(&mut self, fields: OutputFields, t_s: f64) -> (BinaryMessage, TruthSample) {
        let m = self.core.measure(t_s, true);
        let clean = self.core.measure(t_s, false);
        let startup_ns = (self.core.device_time_s(t_s) * 1e9).floor().max(0.0) as u64;
        let period_s = self.core.sample_period_s();
        let f32s = |v: imu_model::nalgebra::Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        let s = &m.state;
        let gnss = has_gnss(&self.model);
        // A VN-200/300's GPS time: the scenario's (`DeviceCore::gnss_time`, valid outside its
        // outages) if it gives the unit one, else the true time, valid.
        let gps = gnss.then(|| {
            let (utc_ns, valid) = self.core.gnss_time(t_s).map_or(
                (GPS_START_UNIX_NS + (t_s * 1e9).round() as i64, true),
                |g| (g.utc_ns, g.valid),
            );
            (unix_ns_to_gps_ns(utc_ns), valid)
        });
        let data = BinaryData {
            startup_ns: Some(startup_ns),
            gps_ns: Some(gps.map_or(0, |(ns, _)| ns)),
            time_status: Some(TimeStatus(if gps.is_some_and(|(_, valid)| valid) {
                0b111
            } else {
                0
            })),
            time_utc: None,
            imu_status: Some(0),
            uncomp_mag_gauss: Some(f32s(m.mag_gauss)),
            uncomp_accel_m_s2: Some(f32s(m.accel_m_s2)),
            uncomp_gyro_rad_s: Some(f32s(m.gyro_rad_s)),
            temp_c: Some(m.conditions.temp_c as f32),
            pres_kpa: Some(PRESSURE_KPA),
            delta_theta: Some(DeltaTheta {
                dt_s: period_s as f32,
                theta_deg: f32s(m.gyro_rad_s * period_s.to_degrees()),
            }),
            delta_vel_m_s: Some(f32s(m.accel_m_s2 * period_s)),
            mag_gauss: Some(f32s(s.mag_field_gauss + (m.mag_gauss - clean.mag_gauss))),
            accel_m_s2: Some(f32s(
                s.specific_force_m_s2 + (m.accel_m_s2 - clean.accel_m_s2),
            )),
            angular_rate_rad_s: Some(f32s(
                s.angular_rate_rad_s + (m.gyro_rad_s - clean.gyro_rad_s),
            )),
        };
        // Every bit of `fields` is one `supported()` holds and `data` fills.
        let message = BinaryMessage::encode(fields, &data)
            .or_else(|_| BinaryMessage::encode(default_fields(gnss), &data))
            .expect("the default fields are all filled");
        let truth = self.core.truth_sample(&m, SYNC, startup_ns, false);
        (message, truth)
    }
}

/// A VN-200 or VN-300 has a GNSS receiver.
pub use imu_proto::vectornav::model_has_gnss as has_gnss;

/// IMU rate / data rate (validated to be whole for a VectorNav scenario).
fn divisor_for(rate_hz: f64) -> u16 {
    (f64::from(IMU_RATE_HZ) / rate_hz).round() as u16
}

/// The scenario's firmware word N as `major.minor.feature.hotfix`: N/1000, (N%1000)/100,
/// N%100, 0 (the GX1's reading of the same word).
fn firmware_text(n: u16) -> String {
    format!("{}.{}.{}.0", n / 1000, (n % 1000) / 100, n % 100)
}

#[cfg(test)]
mod tests;
