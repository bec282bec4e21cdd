//! The per-frame path: decoded frame -> raw sample -> corrected sample -> shared memory and log.
//!
//! Synchronous and allocation-free on the data path (apart from what the log record needs), so
//! it can be benchmarked on its own (`cargo bench -p imud`). The session feeds it every decoder
//! event with the host receive times; it never blocks: publishing overwrites the oldest sample of
//! a slow subscriber and logging drops (and counts) records when the writer thread falls behind.

use std::sync::Arc;

use imu_bus::recording::{ImuNoiseVariances, LogRecord, Recorder};
use imu_bus::sample::{corrected_flags, raw_flags};
use imu_bus::shm::{Publishers, ShmEvent};
use imu_bus::{CorrectedSample, DaemonStatus, RawSample};
use imu_model::nalgebra::Vector3;
use imu_model::{Calibration, Measured};
use imu_proto::decoder::{DecodeEvent, DecoderStats, RejectReason};
use imu_proto::reply::Reply;
use imu_proto::scale;
use imu_proto::ticks::TickUnwrapper;

use crate::clock::ClockFit;

const G0: f64 = imu_model::units::STANDARD_GRAVITY_M_S2;

/// The device's GainScales and whether they are fallbacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gains {
    /// Accelerometer GainScale.
    pub accel: u16,
    /// Gyro GainScale.
    pub gyro: u16,
    /// Magnetometer GainScale.
    pub mag: u16,
    /// True when the EEPROM read failed and configured fallbacks are in use.
    pub fallback: bool,
}

/// The calibration in force, ready for the per-sample path.
#[derive(Debug, Clone)]
pub struct ActiveCalibration {
    /// The model.
    pub model: Calibration,
    /// Its content id as a number (published with every corrected sample).
    pub id: u64,
}

impl ActiveCalibration {
    /// Wraps a loaded calibration.
    pub fn new(model: Calibration) -> Self {
        let id = u64::from_str_radix(&model.content_id(), 16).unwrap_or(0);
        Self { model, id }
    }
}

/// Where the pipeline's output goes.
#[derive(Default)]
pub struct Sinks {
    /// Shared-memory publishers.
    pub publishers: Option<Publishers>,
    /// The MCAP recorder.
    pub recorder: Option<Recorder>,
}

impl Sinks {
    /// Logs a calibration put in force; `sample_rate_hz` turns its white-noise densities into
    /// per-sample variances for the ROS covariance fields (unknown rate: covariance unknown).
    pub fn log_calibration(
        &self,
        t_wall_ns: u64,
        cal: &ActiveCalibration,
        sample_rate_hz: Option<f64>,
    ) {
        let variances = |t: &imu_model::TriadModel, unit_scale: f64| {
            t.noise.as_ref().map(|n| {
                let fs = sample_rate_hz.unwrap_or(f64::NAN);
                n.white_density.map(|d| (d * unit_scale).powi(2) * fs)
            })
        };
        let noise = match (
            sample_rate_hz,
            variances(&cal.model.accel, 1.0),
            variances(&cal.model.gyro, 1.0),
        ) {
            (Some(_), Some(accel_var_m2_s4), Some(gyro_var_rad2_s2)) => Some(ImuNoiseVariances {
                accel_var_m2_s4,
                gyro_var_rad2_s2,
                // gauss -> tesla for sensor_msgs/MagneticField.
                mag_var_t2: variances(&cal.model.mag, 1e-4).unwrap_or([0.0; 3]),
            }),
            _ => None,
        };
        self.log(LogRecord::Calibration {
            t_wall_ns,
            id: format!("{:016x}", cal.id),
            toml: cal.model.to_toml_string(),
            noise,
        });
    }

    fn log(&self, record: LogRecord) {
        if let Some(r) = &self.recorder {
            // A full queue drops the record; the recorder counts it.
            let _ = r.log(record);
        }
    }
}

/// Counters owned by the pipeline.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PipelineCounters {
    /// Good frames seen.
    pub frames: u64,
    /// Data samples produced.
    pub samples: u64,
    /// Samples the device link lost (tick gaps in continuous mode).
    pub samples_lost: u64,
    /// Corrections whose accel/gyro coupling did not converge.
    pub not_converged: u64,
    /// Samples whose shared-memory publication failed.
    pub publish_errors: u64,
}

/// The per-frame state machine.
pub struct Pipeline {
    gains: Gains,
    tick_period_s: f64,
    unwrapper: TickUnwrapper,
    clock: ClockFit,
    calibration: Option<Arc<ActiveCalibration>>,
    temp_c: f64,
    /// Expected ticks between consecutive samples in continuous mode (for gap detection),
    /// learned from the first samples of a session.
    expected_tick_step: Option<f64>,
    /// Whether to learn `expected_tick_step` (continuous mode only: polls are irregular).
    detect_gaps: bool,
    /// Sum and count of tick steps while learning.
    step_stats: (u64, u64),
    last_ticks: Option<u64>,
    last_gyro: Option<(u64, Vector3<f64>)>,
    /// First sample time of the session and samples since (for the sample-rate estimate).
    rate_origin: Option<(u64, u64)>,
    last_sample_ns: Option<u64>,
    seq: u64,
    counters: PipelineCounters,
}

impl Pipeline {
    /// A pipeline for one device session.
    pub fn new(
        gains: Gains,
        tick_period_s: f64,
        calibration: Option<Arc<ActiveCalibration>>,
    ) -> Self {
        Self {
            gains,
            tick_period_s,
            unwrapper: TickUnwrapper::new(),
            clock: ClockFit::new(tick_period_s),
            calibration,
            temp_c: f64::NAN,
            expected_tick_step: None,
            detect_gaps: false,
            step_stats: (0, 0),
            last_ticks: None,
            last_gyro: None,
            rate_origin: None,
            last_sample_ns: None,
            seq: 0,
            counters: PipelineCounters::default(),
        }
    }

    /// Starts a new device session (after a reconnect): keeps the sequence numbering, forgets
    /// the device's clock.
    pub fn new_session(&mut self, gains: Gains) {
        self.gains = gains;
        self.unwrapper = TickUnwrapper::new();
        self.clock.reset();
        self.last_ticks = None;
        self.last_gyro = None;
        self.rate_origin = None;
        self.last_sample_ns = None;
    }

    /// Measured data rate, Hz, once at least two seconds of samples were seen this session.
    pub fn sample_rate_hz(&self) -> Option<f64> {
        let (t0, n0) = self.rate_origin?;
        let (t1, n1) = (self.last_sample_ns?, self.counters.samples);
        let span_s = (t1.saturating_sub(t0)) as f64 * 1e-9;
        (span_s >= 2.0).then(|| (n1 - n0 - 1) as f64 / span_s)
    }

    /// Turns on gap detection for a continuous stream (the device's sample interval is learned
    /// from the first samples' tick steps); off for polling, whose intervals are the host's.
    pub fn set_continuous(&mut self, continuous: bool) {
        self.detect_gaps = continuous;
        self.expected_tick_step = None;
        self.step_stats = (0, 0);
    }

    /// Puts a calibration in force from the next sample on (returns that sample's seq).
    pub fn set_calibration(&mut self, calibration: Option<Arc<ActiveCalibration>>) -> u64 {
        self.calibration = calibration;
        self.seq
    }

    /// The calibration in force.
    pub fn calibration(&self) -> Option<&Arc<ActiveCalibration>> {
        self.calibration.as_ref()
    }

    /// The latest temperature, deg C (NaN if none yet).
    pub fn temp_c(&self) -> f64 {
        self.temp_c
    }

    /// Counters so far.
    pub fn counters(&self) -> PipelineCounters {
        self.counters
    }

    /// The device-clock fit.
    pub fn clock(&self) -> &ClockFit {
        &self.clock
    }

    /// Handles one decoder event received at the given host times.
    pub fn on_event(&mut self, ev: DecodeEvent, t_mono_ns: u64, t_wall_ns: u64, sinks: &mut Sinks) {
        match ev {
            DecodeEvent::Frame {
                reply,
                bytes,
                offset,
            } => {
                self.counters.frames += 1;
                sinks.log(LogRecord::RawFrame {
                    t_host_wall_ns: t_wall_ns,
                    t_host_monotonic_ns: t_mono_ns,
                    stream_offset: offset,
                    accepted: true,
                    reject_reason: None,
                    bytes: bytes.to_vec(),
                });
                self.on_reply(&reply, t_mono_ns, t_wall_ns, sinks);
            }
            DecodeEvent::Rejected {
                bytes,
                offset,
                reason,
            } => sinks.log(LogRecord::RawFrame {
                t_host_wall_ns: t_wall_ns,
                t_host_monotonic_ns: t_mono_ns,
                stream_offset: offset,
                accepted: false,
                reject_reason: Some(std::borrow::Cow::Borrowed(match reason {
                    RejectReason::BadChecksum => "bad-checksum",
                    RejectReason::Malformed => "malformed",
                    RejectReason::Truncated => "truncated",
                    RejectReason::Garbage => "garbage",
                })),
                bytes,
            }),
        }
    }

    /// Handles one good reply.
    pub fn on_reply(&mut self, reply: &Reply, t_mono_ns: u64, t_wall_ns: u64, sinks: &mut Sinks) {
        let (accel, gyro, mag, scaled) = match *reply {
            Reply::Temperature { raw, .. } => {
                self.temp_c = scale::temp_raw_to_c(raw);
                sinks.log(LogRecord::Temperature {
                    t_wall_ns,
                    temp_c: self.temp_c,
                });
                return;
            }
            Reply::RawSensorBits {
                mag, accel, rate, ..
            } => (
                accel.map(i32::from),
                rate.map(i32::from),
                mag.map(i32::from),
                false,
            ),
            Reply::Vectors {
                mag, accel, rate, ..
            }
            | Reply::QuaternionVectors {
                mag, accel, rate, ..
            } => (
                accel.map(i32::from),
                rate.map(i32::from),
                mag.map(i32::from),
                true,
            ),
            _ => return,
        };
        let ticks = reply.ticks().unwrap_or(0);
        let ticks_unwrapped = self.unwrapper.unwrap(ticks);
        let mut flags = if scaled { raw_flags::SCALED_COUNTS } else { 0 };
        if let Some(last) = self.last_ticks
            && self.detect_gaps
        {
            let step = ticks_unwrapped.saturating_sub(last);
            match self.expected_tick_step {
                Some(expected) => {
                    let intervals = (step as f64 / expected).round() as u64;
                    if intervals > 1 {
                        self.counters.samples_lost += intervals - 1;
                        flags |= raw_flags::GAP_BEFORE;
                    }
                }
                None => {
                    // Ticks are coarser than some sample intervals (6.5536 ms vs 10 ms at
                    // 100 Hz), so learn the mean step over the first samples.
                    self.step_stats.0 += step;
                    self.step_stats.1 += 1;
                    if self.step_stats.1 == 128 && self.step_stats.0 > 0 {
                        self.expected_tick_step = Some(self.step_stats.0 as f64 / 128.0);
                    }
                }
            }
        }
        self.last_ticks = Some(ticks_unwrapped);
        if self.temp_c.is_nan() {
            flags |= raw_flags::TEMP_STALE;
        }
        let saturated = |c: &[i32; 3]| {
            c.iter().any(|&v| {
                if scaled {
                    v == i16::MAX as i32 || v == i16::MIN as i32
                } else {
                    v == 0 || v == u16::MAX as i32
                }
            })
        };
        if saturated(&accel) || saturated(&gyro) || saturated(&mag) {
            flags |= raw_flags::SATURATED;
        }
        let t_sample_ns = self.clock.update(ticks_unwrapped, t_mono_ns);
        let t_device_ns = (ticks_unwrapped as f64 * self.tick_period_s * 1e9) as u64;
        let raw = RawSample {
            seq: self.seq,
            t_device_ns,
            t_host_monotonic_ns: t_mono_ns,
            t_host_wall_ns: t_wall_ns,
            t_sample_ns,
            ticks_unwrapped,
            accel_counts: accel,
            gyro_counts: gyro,
            mag_counts: mag,
            temp_c: self.temp_c,
            ticks,
            command: reply.code(),
            reserved: 0,
            flags,
        };
        let to_units = |c: i32, gain: u16| {
            if scaled {
                scale::scaled_to_units(c as i16, gain)
            } else {
                scale::raw_bits_to_units(c as u16, gain)
            }
        };
        let g = self.gains;
        let measured = Measured {
            accel_m_s2: Vector3::from_fn(|i, _| to_units(accel[i], g.accel) * G0),
            gyro_rad_s: Vector3::from_fn(|i, _| to_units(gyro[i], g.gyro)),
            mag_gauss: Vector3::from_fn(|i, _| to_units(mag[i], g.mag)),
        };
        let mut cflags = if g.fallback {
            corrected_flags::FALLBACK_GAINS
        } else {
            0
        };
        if self.temp_c.is_nan() {
            cflags |= corrected_flags::TEMP_STALE;
        }
        let (accel_si, gyro_si, mag_si, calibration_id) = match &self.calibration {
            Some(cal) => {
                // Angular acceleration for the lever-arm term: finite difference of the corrected
                // rate (one sample late, which the lever-arm magnitude makes negligible).
                let angular_accel = match self.last_gyro {
                    Some((t_prev, w_prev)) if t_sample_ns > t_prev => {
                        (measured.gyro_rad_s - w_prev) / ((t_sample_ns - t_prev) as f64 * 1e-9)
                    }
                    _ => Vector3::zeros(),
                };
                let temp = if self.temp_c.is_nan() {
                    25.0
                } else {
                    self.temp_c
                };
                let c =
                    cal.model
                        .correct(&measured, temp, t_device_ns as f64 * 1e-9, angular_accel);
                if !c.converged {
                    cflags |= corrected_flags::NOT_CONVERGED;
                    self.counters.not_converged += 1;
                }
                self.last_gyro = Some((t_sample_ns, c.gyro_rad_s));
                (c.accel_m_s2, c.gyro_rad_s, c.mag_gauss, cal.id)
            }
            None => {
                cflags |= corrected_flags::UNCALIBRATED;
                (
                    measured.accel_m_s2,
                    measured.gyro_rad_s,
                    measured.mag_gauss,
                    0,
                )
            }
        };
        let t_wall_sample_ns = t_wall_ns.saturating_sub(t_mono_ns.saturating_sub(t_sample_ns));
        let corrected = CorrectedSample {
            seq: self.seq,
            t_sample_ns,
            t_wall_ns: t_wall_sample_ns,
            t_device_ns,
            accel_m_s2: accel_si.into(),
            gyro_rad_s: gyro_si.into(),
            mag_gauss: mag_si.into(),
            temp_c: self.temp_c,
            calibration_id,
            flags: cflags,
            reserved: 0,
        };
        self.rate_origin
            .get_or_insert((t_sample_ns, self.counters.samples));
        self.last_sample_ns = Some(t_sample_ns);
        self.seq += 1;
        self.counters.samples += 1;
        if let Some(p) = &mut sinks.publishers {
            let sent = p.publish_raw(&raw).is_ok()
                & p.publish_corrected(&corrected).is_ok()
                & p.notify(ShmEvent::Samples).is_ok();
            if !sent {
                self.counters.publish_errors += 1;
            }
        }
        sinks.log(LogRecord::Raw(raw));
        sinks.log(LogRecord::Corrected(corrected));
    }

    /// Builds the status record from the pipeline's, the decoder's and the sinks' counters.
    pub fn status(
        &self,
        decoder: &DecoderStats,
        sinks: &Sinks,
        reconnects: u64,
        connected: bool,
        t_mono_ns: u64,
    ) -> DaemonStatus {
        let (log_drops, logging) = sinks.recorder.as_ref().map_or((0, false), |r| {
            let s = r.stats();
            (s.dropped_queue_full + s.dropped_not_logging, s.logging)
        });
        DaemonStatus {
            t_host_monotonic_ns: t_mono_ns,
            frames: self.counters.frames,
            samples: self.counters.samples,
            checksum_failures: decoder.checksum_failures,
            resyncs: decoder.resyncs,
            garbage_bytes: decoder.garbage_bytes,
            truncated_frames: decoder.truncated_frames,
            samples_lost: self.counters.samples_lost,
            log_drops,
            publish_drops: sinks.publishers.as_ref().map_or(0, Publishers::drops)
                + self.counters.publish_errors,
            reconnects,
            calibration_id: self.calibration.as_ref().map_or(0, |c| c.id),
            tick_period_est_s: self.clock.tick_period_s().unwrap_or(f64::NAN),
            clock_drift_ppm: self.clock.drift_ppm().unwrap_or(f64::NAN),
            temp_c: self.temp_c,
            device_connected: u8::from(connected),
            logging: u8::from(logging),
            reserved: [0; 6],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(ticks: u16) -> Reply {
        Reply::RawSensorBits {
            mag: [32_768; 3],
            accel: [32_768, 32_768, 32_768 + 4681],
            rate: [32_768; 3],
            ticks,
        }
    }

    #[test]
    fn continuous_gaps_are_counted_and_flagged() {
        let gains = Gains {
            accel: 7000,
            gyro: 10000,
            mag: 2000,
            fallback: false,
        };
        let mut p = Pipeline::new(gains, 6.5536e-3, None);
        p.set_continuous(true);
        let mut sinks = Sinks::default();
        let lost = [300u64, 301, 302, 500];
        for k in 0..1000u64 {
            if lost.contains(&k) {
                continue;
            }
            // 100 Hz on 6.5536 ms ticks: steps of 1 and 2 ticks, and a wrap past 65535.
            let ticks = ((k as f64 * 0.01 / 6.5536e-3).floor() as u64 + 65_000) % 65_536;
            p.on_reply(
                &raw(ticks as u16),
                k * 10_000_000,
                k * 10_000_000,
                &mut sinks,
            );
        }
        assert_eq!(p.counters().samples, 996);
        assert_eq!(p.counters().samples_lost, 4);
        // Without a calibration the corrected stream is the GainScale conversion: z = +1 g.
        assert!(p.calibration().is_none());
    }

    #[test]
    fn polled_streams_do_not_count_gaps() {
        let gains = Gains {
            accel: 7000,
            gyro: 10000,
            mag: 2000,
            fallback: true,
        };
        let mut p = Pipeline::new(gains, 6.5536e-3, None);
        p.set_continuous(false);
        let mut sinks = Sinks::default();
        for k in 0..300u64 {
            let ticks = (k * k) % 65_536; // irregular polls
            p.on_reply(&raw(ticks as u16), k, k, &mut sinks);
        }
        assert_eq!(p.counters().samples_lost, 0);
    }
}
