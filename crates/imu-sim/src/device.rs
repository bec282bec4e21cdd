//! The virtual 3DM-GX1 itself, without I/O: answers commands and produces data replies from the
//! true motion, the truth error model and the noise processes.
//!
//! [`DeviceCore`] is sans-IO like the codec: the pty loop in [`crate::link`] owns the clock and the
//! file descriptors and asks the core for replies. Each data reply comes with the
//! [`TruthSample`] that produced it, so the truth file can reproduce every streamed value.
//!
//! What the virtual device does that a host can rely on:
//! - Scaled vectors (0x02, 0x03, 0x0C, 0x12, 0x31) and raw bits (0x01) encode the same measured
//!   values (truth model + noise), quantized to 16 bits with the EEPROM GainScales; saturation is
//!   flagged in the truth. Stabilized and instantaneous variants carry the same values.
//! - Orientation replies encode the true orientation relative to North-East-Down (after a tare,
//!   relative to the tared orientation): quaternion `[w, x, y, z]` of `ned_from_sensor`; the
//!   matrix as the nine elements of `sensor_from_ned` in row order (which drivers read as the
//!   transposed `ned_from_sensor`); Euler roll, pitch, yaw (Z-Y-X) of `ned_from_sensor`.
//! - "Capture gyro bias" (0x06) records the noise-free gyro output at that moment (Earth rate,
//!   truth bias and all) and subtracts it from the scaled rate vectors; raw bits never change.
//! - EEPROM holds the GainScales at 130/230/232 and accepts writes to any address.

use std::collections::BTreeMap;

use imu_model::nalgebra::{UnitQuaternion, Vector3};
use imu_model::{Calibration, Conditions, NoiseGenerator, TrueMotion};
use imu_proto::command::Command;
use imu_proto::device::{ACCEL_GAIN_SCALE_ADDR, GYRO_GAIN_SCALE_ADDR, MAG_GAIN_SCALE_ADDR};
use imu_proto::gnss_time::GnssTime;
use imu_proto::reply::{Filter, Reply};
use imu_proto::scale;
use imu_rec::truth::TruthSample;

use crate::motion::{MotionState, Timeline};
use crate::scenario::{Scenario, enu_from_ned};

/// What the device does in answer to one command.
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    /// The reply to send (`None`: the device stays silent, e.g. a failing EEPROM read).
    pub reply: Option<Reply>,
    /// The truth behind a data reply.
    pub truth: Option<TruthSample>,
    /// How long the real device takes before it answers, seconds.
    pub delay_s: f64,
}

/// Counters of what the device did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeviceStats {
    /// Data replies produced.
    pub data_replies: u64,
    /// Commands answered.
    pub commands: u64,
    /// Replies with at least one saturated channel.
    pub saturated_replies: u64,
}

/// The sans-IO virtual device.
pub struct DeviceCore {
    scenario: Scenario,
    timeline: Timeline,
    truth: Calibration,
    noise: [Option<NoiseGenerator>; 3],
    eeprom: BTreeMap<u16, u16>,
    streaming: Option<Command>,
    seq: u64,
    gyro_offset_rad_s: Vector3<f64>,
    tare_ned_from_sensor: Option<UnitQuaternion<f64>>,
    stats: DeviceStats,
}

/// Splits one seed into independent stream seeds (SplitMix64 finaliser).
fn derive_seed(seed: u64, stream: u64) -> u64 {
    let mut z = seed.wrapping_add(stream.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl DeviceCore {
    /// A powered-on device for `scenario` with the `truth` error model: idle, or streaming
    /// raw sensor bits in continuous mode if the scenario's device powers up streaming.
    pub fn new(scenario: Scenario, truth: Calibration, seed: u64) -> Self {
        let timeline = scenario.compile(seed);
        let rate = scenario.rate_hz;
        // One independent, reproducible noise stream per triad.
        let models = [&truth.accel, &truth.gyro, &truth.mag];
        let noise = std::array::from_fn(|i| {
            models[i]
                .noise
                .as_ref()
                .map(|n| NoiseGenerator::new(n, rate, derive_seed(seed, i as u64 + 1)))
        });
        let g = scenario.device.gain_scale;
        // A unit saved in continuous mode streams raw sensor bits from power-up.
        let streaming = scenario
            .device
            .power_up_streaming
            .then_some(Command::RawSensorBits);
        let eeprom = BTreeMap::from([
            (GYRO_GAIN_SCALE_ADDR, g.gyro),
            (ACCEL_GAIN_SCALE_ADDR, g.accel),
            (MAG_GAIN_SCALE_ADDR, g.mag),
        ]);
        Self {
            scenario,
            timeline,
            truth,
            noise,
            eeprom,
            streaming,
            seq: 0,
            gyro_offset_rad_s: Vector3::zeros(),
            tare_ned_from_sensor: None,
            stats: DeviceStats::default(),
        }
    }

    /// The scenario being run.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The compiled motion.
    pub fn timeline(&self) -> &Timeline {
        &self.timeline
    }

    /// The truth error model.
    pub fn truth_model(&self) -> &Calibration {
        &self.truth
    }

    /// The command being streamed in continuous mode, if any.
    pub fn streaming(&self) -> Option<Command> {
        self.streaming
    }

    /// Counters.
    pub fn stats(&self) -> DeviceStats {
        self.stats
    }

    /// True time between continuous-mode samples: the device paces them on its own oscillator,
    /// so a fast clock (positive drift) sends them slightly early.
    pub fn sample_period_s(&self) -> f64 {
        1.0 / (self.scenario.rate_hz * (1.0 + self.scenario.device.clock_drift_ppm * 1e-6))
    }

    /// The device's unwrapped timer ticks at scenario time `t_s`.
    pub fn ticks_unwrapped(&self, t_s: f64) -> u64 {
        let d = &self.scenario.device;
        d.initial_ticks + (self.device_time_s(t_s) / d.tick_period_s).floor().max(0.0) as u64
    }

    /// Time since power-on on the device's own oscillator (which runs `clock-drift-ppm` fast)
    /// at scenario time `t_s`, seconds.
    pub fn device_time_s(&self, t_s: f64) -> f64 {
        let d = &self.scenario.device;
        (t_s + self.scenario.power_on_before_s) * (1.0 + d.clock_drift_ppm * 1e-6)
    }

    /// The unit's GNSS time at scenario time `t_s` when the scenario gives it one
    /// (`device.gnss-time`), the same for every protocol that carries one: the true UTC
    /// (`gnss-epoch-utc-s` + `t_s`), valid, outside the `gnss-outage` windows; inside one, the
    /// unit's own propagation on its drifting clock from the outage's start (its last fix),
    /// not valid. `None` without `device.gnss-time`: each protocol then sends what such a unit
    /// sends.
    pub fn gnss_time(&self, t_s: f64) -> Option<GnssTime> {
        let d = &self.scenario.device;
        if !d.gnss_time {
            return None;
        }
        let epoch_ns = (d.gnss_epoch_utc_s * 1e9).round() as i64;
        let at = |t_s: f64| epoch_ns + (t_s * 1e9).round() as i64;
        if d.gnss_valid_at(t_s) {
            return Some(GnssTime {
                utc_ns: at(t_s),
                valid: true,
            });
        }
        // The last fix: the start of the outage this time is in (scenario time 0 at the
        // latest, before which the unit had none).
        let fix_s = d
            .gnss_outage
            .iter()
            .filter(|o| (o.start_s..o.end_s).contains(&t_s))
            .map(|o| o.start_s.max(0.0))
            .fold(t_s, f64::min);
        let since_s = self.device_time_s(t_s) - self.device_time_s(fix_s);
        Some(GnssTime {
            utc_ns: at(fix_s) + (since_s * 1e9).round() as i64,
            valid: false,
        })
    }

    fn ticks(&self, t_s: f64) -> u16 {
        (self.ticks_unwrapped(t_s) % 65_536) as u16
    }

    /// Answers one host command at scenario time `t_s`.
    pub fn handle(&mut self, cmd: Command, t_s: f64) -> Response {
        self.stats.commands += 1;
        let ticks = self.ticks(t_s);
        let plain = |reply: Reply| Response {
            reply: Some(reply),
            truth: None,
            delay_s: 0.0,
        };
        match cmd {
            Command::SetContinuous { command } => {
                self.streaming = if command == 0 {
                    None
                } else {
                    Command::from_code(command).filter(|c| c.is_data())
                };
                plain(Reply::Continuous { command, ticks })
            }
            Command::Tare => {
                self.tare_ned_from_sensor = Some(self.ned_from_sensor(&self.timeline.state(t_s)));
                plain(Reply::Tare { ticks })
            }
            Command::RemoveTare => {
                self.tare_ned_from_sensor = None;
                plain(Reply::RemoveTare { ticks })
            }
            Command::ReadEeprom { address } => {
                if self.scenario.device.eeprom_read_fails {
                    return Response {
                        reply: None,
                        truth: None,
                        delay_s: 0.0,
                    };
                }
                let value = self.eeprom.get(&address).copied().unwrap_or(0);
                plain(Reply::EepromRead { value, ticks })
            }
            Command::WriteEeprom { address, value } => {
                self.eeprom.insert(address, value);
                plain(Reply::EepromWrite { value, ticks })
            }
            Command::FirmwareVersion => plain(Reply::FirmwareVersion {
                version: self.scenario.device.firmware,
            }),
            Command::SerialNumber => plain(Reply::SerialNumber {
                serial: self.scenario.device.serial_number,
            }),
            Command::CaptureGyroBias => {
                let state = self.timeline.state(t_s);
                let (_, gyro, _) = self.deterministic(&state, t_s);
                self.gyro_offset_rad_s = gyro;
                Response {
                    reply: Some(Reply::CaptureGyroBias { ticks }),
                    truth: None,
                    delay_s: self.scenario.device.capture_bias_s,
                }
            }
            data => {
                let (reply, truth) = self.data_reply(data, t_s);
                Response {
                    reply: Some(reply),
                    truth: Some(truth),
                    delay_s: 0.0,
                }
            }
        }
    }

    fn conditions(&self, state: &MotionState, t_s: f64) -> Conditions {
        let power_on_s = t_s + self.scenario.power_on_before_s;
        Conditions {
            temp_c: self.scenario.temperature.temp_c(power_on_s),
            time_since_power_on_s: power_on_s,
            specific_force_m_s2: state.specific_force_m_s2,
            angular_rate_rad_s: state.angular_rate_rad_s,
            angular_accel_rad_s2: state.angular_accel_rad_s2,
        }
    }

    /// Truth model output without noise: (accel m/s^2, gyro rad/s, mag gauss).
    fn deterministic(
        &self,
        state: &MotionState,
        t_s: f64,
    ) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let c = self.conditions(state, t_s);
        let m = self.truth.forward(
            &TrueMotion {
                specific_force_m_s2: state.specific_force_m_s2,
                angular_rate_rad_s: state.angular_rate_rad_s,
                angular_accel_rad_s2: state.angular_accel_rad_s2,
                mag_field_gauss: state.mag_field_gauss,
            },
            &c,
        );
        (m.accel_m_s2, m.gyro_rad_s, m.mag_gauss)
    }

    pub(crate) fn ned_from_sensor(&self, state: &MotionState) -> UnitQuaternion<f64> {
        enu_from_ned().inverse() * state.enu_from_sensor
    }

    /// Produces the data reply `cmd` (which must be a data command) at scenario time `t_s`.
    pub fn data_reply(&mut self, cmd: Command, t_s: f64) -> (Reply, TruthSample) {
        // Temperature polls do not consume noise, so the IMU noise sequence is the same whether
        // or not the host interleaves temperature reads.
        let m = self.measure(t_s, cmd != Command::Temperature);
        let ticks_unwrapped = self.ticks_unwrapped(t_s);
        let ticks = (ticks_unwrapped % 65_536) as u16;
        let (reply, saturated) = self.gx1_reply(cmd, &m, ticks);
        let truth = self.truth_sample(&m, cmd.code(), ticks_unwrapped, saturated);
        (reply, truth)
    }

    /// The sensor output at scenario time `t_s` before any protocol's encoding: truth model,
    /// disturbances and (when `with_noise`) the next noise sample of each triad.
    pub fn measure(&mut self, t_s: f64, with_noise: bool) -> Measurement {
        let state = self.timeline.state(t_s);
        let conditions = self.conditions(&state, t_s);
        let (mut accel, mut gyro, mut mag) = self.deterministic(&state, t_s);
        for d in &self.scenario.disturbances {
            match d.triad {
                imu_model::Triad::Accel => accel += d.at(t_s),
                imu_model::Triad::Gyro => gyro += d.at(t_s),
                imu_model::Triad::Mag => mag += d.at(t_s),
            }
        }
        if with_noise {
            for (v, n) in [&mut accel, &mut gyro, &mut mag]
                .into_iter()
                .zip(self.noise.iter_mut())
            {
                if let Some(n) = n {
                    *v += n.next();
                }
            }
        }
        Measurement {
            t_s,
            state,
            conditions,
            accel_m_s2: accel,
            gyro_rad_s: gyro,
            mag_gauss: mag,
        }
    }

    /// The 3DM-GX1 reply to data command `cmd` carrying `m`, and whether a channel saturated.
    fn gx1_reply(&self, cmd: Command, m: &Measurement, ticks: u16) -> (Reply, bool) {
        let g0 = imu_model::units::STANDARD_GRAVITY_M_S2;
        let gains = self.gains();
        let mut saturated = false;
        let mut scaled = |v: Vector3<f64>, gain: u16| -> [i16; 3] {
            std::array::from_fn(|i| {
                let q = scale::units_to_scaled(v[i], gain);
                saturated |= q.saturated;
                q.counts
            })
        };
        let accel = scaled(m.accel_m_s2 / g0, gains.0);
        let rate = scaled(m.gyro_rad_s - self.gyro_offset_rad_s, gains.1);
        let mag = scaled(m.mag_gauss, gains.2);
        let o = self.orientation_counts(&m.state);
        let reply = match cmd {
            Command::RawSensorBits => {
                let mut raw = |v: Vector3<f64>, gain: u16| -> [u16; 3] {
                    std::array::from_fn(|i| {
                        let q = scale::units_to_raw_bits(v[i], gain);
                        saturated |= q.saturated;
                        q.counts
                    })
                };
                Reply::RawSensorBits {
                    mag: raw(m.mag_gauss, gains.2),
                    accel: raw(m.accel_m_s2 / g0, gains.0),
                    rate: raw(m.gyro_rad_s, gains.1),
                    ticks,
                }
            }
            Command::Temperature => {
                let t = scale::temp_c_to_raw(m.conditions.temp_c);
                saturated |= t.saturated;
                Reply::Temperature {
                    raw: t.counts,
                    ticks,
                }
            }
            _ => gx1_vector_reply(cmd, accel, rate, mag, &o, ticks),
        };
        (reply, saturated)
    }

    /// The orientation replies' counts: after a tare, relative to the tared orientation.
    fn orientation_counts(&self, state: &MotionState) -> OrientationCounts {
        let ned_from_sensor = match self.tare_ned_from_sensor {
            Some(tare) => tare.inverse() * self.ned_from_sensor(state),
            None => self.ned_from_sensor(state),
        };
        let qv = ned_from_sensor.quaternion();
        let q = [qv.w, qv.i, qv.j, qv.k].map(|v| scale::value_to_quat_matrix_counts(v).counts);
        let (roll, pitch, yaw) = ned_from_sensor.euler_angles();
        let rpy = [roll, pitch, yaw].map(|a| scale::deg_to_euler_counts(a.to_degrees()).counts);
        let sensor_from_ned = ned_from_sensor.inverse().to_rotation_matrix();
        let m = std::array::from_fn(|k| {
            scale::value_to_quat_matrix_counts(sensor_from_ned[(k / 3, k % 3)]).counts
        });
        OrientationCounts { q, rpy, m }
    }

    /// The truth record of one data reply of header `command` made from `m` (the reply's
    /// ticks are `ticks_unwrapped`), counted as a data reply.
    pub fn truth_sample(
        &mut self,
        m: &Measurement,
        command: u8,
        ticks_unwrapped: u64,
        saturated: bool,
    ) -> TruthSample {
        self.stats.data_replies += 1;
        if saturated {
            self.stats.saturated_replies += 1;
        }
        let state = &m.state;
        let q = state.enu_from_sensor.quaternion();
        let truth = TruthSample {
            seq: self.seq,
            command,
            ticks: (ticks_unwrapped % 65_536) as u16,
            ticks_unwrapped,
            t_s: m.t_s,
            time_since_power_on_s: m.conditions.time_since_power_on_s,
            segment: state.segment,
            specific_force_m_s2: state.specific_force_m_s2.into(),
            angular_rate_rad_s: state.angular_rate_rad_s.into(),
            angular_accel_rad_s2: state.angular_accel_rad_s2.into(),
            mag_field_gauss: state.mag_field_gauss.into(),
            temp_c: m.conditions.temp_c,
            enu_from_sensor: [q.w, q.i, q.j, q.k],
            table_angle_rad: state.table_angle_rad,
            table_rate_rad_s: state.table_rate_rad_s,
            measured_accel_m_s2: m.accel_m_s2.into(),
            measured_gyro_rad_s: m.gyro_rad_s.into(),
            measured_mag_gauss: m.mag_gauss.into(),
            saturated,
        };
        self.seq += 1;
        truth
    }

    /// GainScales currently in EEPROM (a host may rewrite them): (accel, gyro, mag).
    fn gains(&self) -> (u16, u16, u16) {
        let get = |a: u16| {
            self.eeprom
                .get(&a)
                .copied()
                .filter(|&g| g != 0)
                .unwrap_or(1)
        };
        (
            get(ACCEL_GAIN_SCALE_ADDR),
            get(GYRO_GAIN_SCALE_ADDR),
            get(MAG_GAIN_SCALE_ADDR),
        )
    }
}

/// One sensor output before encoding (see [`DeviceCore::measure`]).
#[derive(Debug, Clone)]
pub struct Measurement {
    /// Scenario time, s.
    pub t_s: f64,
    /// The true motion.
    pub state: MotionState,
    /// Temperature and time since power-on.
    pub conditions: Conditions,
    /// Accelerometer output, m/s^2.
    pub accel_m_s2: Vector3<f64>,
    /// Gyro output, rad/s.
    pub gyro_rad_s: Vector3<f64>,
    /// Magnetometer output, gauss.
    pub mag_gauss: Vector3<f64>,
}

/// Orientation in the GX1's count encodings.
struct OrientationCounts {
    /// Quaternion `[w, x, y, z]` of `ned_from_sensor`.
    q: [i16; 4],
    /// Euler roll, pitch, yaw.
    rpy: [i16; 3],
    /// `sensor_from_ned`, row order.
    m: [i16; 9],
}

/// The GX1 replies made of scaled vectors and orientation.
fn gx1_vector_reply(
    cmd: Command,
    accel: [i16; 3],
    rate: [i16; 3],
    mag: [i16; 3],
    o: &OrientationCounts,
    ticks: u16,
) -> Reply {
    let (q, rpy, m) = (o.q, o.rpy, o.m);
    match cmd {
        Command::StabilizedVectors | Command::InstantaneousVectors => Reply::Vectors {
            kind: filter_of(cmd),
            mag,
            accel,
            rate,
            ticks,
        },
        Command::InstantaneousQuaternion | Command::StabilizedQuaternion => Reply::Quaternion {
            kind: filter_of(cmd),
            q,
            ticks,
        },
        Command::InstantaneousOrientationMatrix | Command::StabilizedOrientationMatrix => {
            Reply::OrientationMatrix {
                kind: filter_of(cmd),
                m,
                ticks,
            }
        }
        Command::StabilizedQuaternionVectors | Command::InstantaneousQuaternionVectors => {
            Reply::QuaternionVectors {
                kind: filter_of(cmd),
                q,
                mag,
                accel,
                rate,
                ticks,
            }
        }
        Command::InstantaneousEuler | Command::StabilizedEuler => Reply::Euler {
            kind: filter_of(cmd),
            rpy,
            ticks,
        },
        Command::StabilizedEulerVectors => Reply::EulerVectors {
            rpy,
            accel,
            rate,
            ticks,
        },
        other => unreachable!("{other:?} is not a data command"),
    }
}

fn filter_of(cmd: Command) -> Filter {
    match cmd {
        Command::StabilizedVectors
        | Command::StabilizedQuaternion
        | Command::StabilizedOrientationMatrix
        | Command::StabilizedQuaternionVectors
        | Command::StabilizedEuler => Filter::Stabilized,
        _ => Filter::Instantaneous,
    }
}
