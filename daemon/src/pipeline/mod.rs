//! The per-frame path: decoded frame -> raw sample -> corrected sample -> shared memory and log.
//!
//! Synchronous and allocation-free on the data path (apart from what the log record needs), so
//! it can be benchmarked on its own (`cargo bench -p imud`). The session feeds it every decoder
//! event with the host receive times; it never blocks: publishing overwrites the oldest sample of
//! a slow subscriber and logging drops (and counts) records when the writer thread falls behind.

//!
//! Files: `reading.rs` (what a driver hands over: a [`DeviceReading`] per data frame, a
//! [`SessionSpec`] per session), `loss/` (gap accounting on the device clock, the one home of
//! it); `sinks.rs` (the calibration in force and the outputs), `readers.rs` (the readers'
//! socket server). Here: the steps every device
//! shares (stamp, correct, watch health, publish) and the status. Nothing here knows a
//! protocol: the drivers (`crate::drivers`) decode frames into these types.

pub mod loss;
pub mod readers;
mod reading;
mod sinks;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use imu_bus::CalibrationHealth;
use imu_bus::recording::{DeviceCompensated, FrameData, LogRecord, SampleFrame};
use imu_bus::sample::HealthState;
use imu_bus::sample::{corrected_flags, raw_flags};
use imu_bus::shm::{Publishers, ShmEvent};
use imu_bus::{CorrectedSample, DaemonStatus, RawSample};
use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use imu_proto::decoder::{DecoderStats, RejectReason};
use tracing::{info, warn};

use crate::clock::{ClockFit, GnssClock, WallStamps};
use crate::config::{HealthConfig, TimeSource};
use crate::health::HealthMonitor;

use loss::GapAccounting;
pub use loss::TickKind;
pub use reading::{
    Acquisition, Counts, DeviceReading, FrameContent, FrameSlot, GainFallback, Gains, SessionSpec,
    TemperatureCadence, TickLength, Timebase,
};
pub use sinks::{ActiveCalibration, Sinks};

/// Smallest spacing of two host stamps, ns (frames read together share their host times).
const MIN_HOST_SPACING_NS: u64 = 1_000;

/// Host time between two recorded temperatures of a stream that sends one with every sample, ns.
const TEMPERATURE_LOG_INTERVAL_NS: u64 = 1_000_000_000;

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
    /// Data frames that were not samples (undecodable, or without the configured clock, accel
    /// or gyro field).
    pub undecodable: u64,
    /// Data fields skipped (unknown descriptors or unexpected sizes).
    pub fields_skipped: u64,
    /// Temperatures recorded.
    pub temperatures: u64,
}

/// Where a sample's time stamps come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SampleClock {
    /// The device's ticks mapped onto the host clock by the clock fit (a real link;
    /// `device.time-source = "device"`).
    #[default]
    DeviceFit,
    /// The host times the frame is handed over with, as is (only kept strictly increasing):
    /// `device.time-source = "host"`, and the offline path, whose "host" time is the simulated
    /// device's exact sample time.
    Host,
    /// Monotonic stamps from the clock fit, wall stamps from the unit's GNSS time
    /// ([`GnssClock`]; `device.time-source = "gnss"`).
    Gnss,
}

/// The per-frame state machine.
pub struct Pipeline {
    sample_clock: SampleClock,
    session: SessionSpec,
    gaps: GapAccounting,
    clock: ClockFit,
    wall: WallStamps,
    gnss: GnssClock,
    /// The last (monotonic, wall) stamps of the run, for the host stamps' order.
    last_host_stamps: Option<(u64, u64)>,
    calibration: Option<Arc<ActiveCalibration>>,
    temp_c: f64,
    /// When a temperature that comes with every sample was last recorded.
    temp_logged_ns: Option<u64>,
    /// The last two corrected rates with their times (older first), for the angular
    /// acceleration of the lever-arm term.
    last_gyro: [Option<(u64, Vector3<f64>)>; 2],
    /// First sample time of the session and samples since (for the sample-rate estimate).
    rate_origin: Option<(u64, u64)>,
    last_sample_ns: Option<u64>,
    seq: u64,
    counters: PipelineCounters,
    /// The health settings (none: health is off) and the monitor of the calibration in force.
    health_config: Option<HealthConfig>,
    health: Option<HealthMonitor>,
    /// The newest health report not yet taken.
    health_report: Option<CalibrationHealth>,
    /// The accepted frame being handled, until its sample takes it into the one record logged
    /// per frame ([`LogRecord::Sample`]); a frame that makes no sample is logged on its own
    /// ([`Pipeline::flush_frame`]) before anything else is, so the log keeps the arrival order.
    pending_frame: Option<SampleFrame>,
}

impl Pipeline {
    /// A pipeline whose first session is `session` (a driver's [`SessionSpec`]; start-up
    /// replaces it with [`Pipeline::new_session`]).
    pub fn new(session: SessionSpec, calibration: Option<Arc<ActiveCalibration>>) -> Self {
        Self {
            sample_clock: SampleClock::default(),
            session,
            gaps: GapAccounting::new(session.acquisition, session.timebase.kind),
            clock: ClockFit::new(session.timebase.tick_period_s()),
            wall: WallStamps::default(),
            gnss: GnssClock::new(),
            last_host_stamps: None,
            calibration,
            temp_c: f64::NAN,
            temp_logged_ns: None,
            last_gyro: [None; 2],
            rate_origin: None,
            last_sample_ns: None,
            seq: 0,
            counters: PipelineCounters::default(),
            health_config: None,
            health: None,
            health_report: None,
            pending_frame: None,
        }
    }

    /// Turns the live calibration health on (with these settings) or off.
    pub fn set_health(&mut self, config: Option<HealthConfig>) {
        self.health_config = config.filter(|c| c.enabled);
        self.restart_health();
    }

    /// A fresh monitor for the calibration in force.
    fn restart_health(&mut self) {
        self.health = self
            .health_config
            .as_ref()
            .map(|c| HealthMonitor::new(c, self.calibration.as_deref()));
    }

    /// The newest health report since the last call (one per still window).
    pub fn take_health(&mut self) -> Option<CalibrationHealth> {
        self.health_report.take()
    }

    /// The health states (accel, gyro) of the calibration in force, when health is on.
    pub fn health_states(&self) -> Option<(HealthState, HealthState)> {
        self.health.as_ref().map(HealthMonitor::states)
    }

    /// Chooses where sample stamps come from (default: the device clock fit).
    pub fn set_sample_clock(&mut self, clock: SampleClock) {
        self.sample_clock = clock;
    }

    /// Stamps as `device.time-source` says.
    pub fn set_time_source(&mut self, source: TimeSource) {
        self.set_sample_clock(match source {
            TimeSource::Host => SampleClock::Host,
            TimeSource::Device => SampleClock::DeviceFit,
            TimeSource::Gnss => SampleClock::Gnss,
        });
    }

    /// The GNSS stamping state.
    pub fn gnss_clock(&self) -> &GnssClock {
        &self.gnss
    }

    /// Starts a new device session (after a start-up or a reconnect): keeps the sequence
    /// numbering and the stamps' order, forgets the device's clock.
    pub fn new_session(&mut self, session: SessionSpec) {
        let timebase = session.timebase;
        self.session = session;
        self.gaps = GapAccounting::new(session.acquisition, timebase.kind);
        if self.clock.nominal_tick_period_s() != timebase.tick_period_s() {
            self.clock = ClockFit::new(timebase.tick_period_s());
        }
        self.clock.reset();
        self.gnss.reset();
        if let Some(h) = &mut self.health {
            h.interrupt();
        }
        self.last_gyro = [None; 2];
        self.rate_origin = None;
        self.last_sample_ns = None;
    }

    /// The monotonic stamp of the last sample of this session, ns.
    pub fn last_stamp_ns(&self) -> Option<u64> {
        self.last_sample_ns
    }

    /// The GainScales in force.
    pub fn gains(&self) -> Gains {
        self.session.gains
    }

    /// The session's device clock and acquisition.
    pub fn session(&self) -> SessionSpec {
        self.session
    }

    /// The data rate, Hz: the poll rate when the host polls, else measured, once at least two
    /// seconds of samples were seen this session (whatever the configuration asked: a device
    /// that streams is measured).
    pub fn sample_rate_hz(&self) -> Option<f64> {
        match self.session.acquisition {
            Acquisition::Polled { rate_hz } => Some(rate_hz),
            Acquisition::Streaming => self.measured_rate_hz(),
        }
    }

    /// Measured data rate, Hz, once at least two seconds of samples were seen this session.
    pub fn measured_rate_hz(&self) -> Option<f64> {
        let (t0, n0) = self.rate_origin?;
        let (t1, n1) = (self.last_sample_ns?, self.counters.samples);
        let span_s = (t1.saturating_sub(t0)) as f64 * 1e-9;
        (span_s >= 2.0).then(|| (n1 - n0 - 1) as f64 / span_s)
    }

    /// Puts a calibration in force from the next sample on (returns that sample's seq).
    pub fn set_calibration(&mut self, calibration: Option<Arc<ActiveCalibration>>) -> u64 {
        self.calibration = calibration;
        self.restart_health();
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

    /// Handles one good frame from the device (in the driver's `slot`) received at the given
    /// host times: it is logged once (with its sample, if it makes one), its temperature kept
    /// and recorded, its reading through the shared steps. The slot's frame is taken only if a
    /// sink logs it.
    pub fn on_frame(
        &mut self,
        slot: &mut FrameSlot,
        t_mono_ns: u64,
        t_wall_ns: u64,
        sinks: &mut Sinks,
    ) {
        self.counters.frames += 1;
        if sinks.logs() {
            self.hold_frame(std::mem::take(&mut slot.frame));
        }
        let content = &slot.content;
        self.counters.fields_skipped += u64::from(content.fields_skipped);
        if let Some((temp_c, cadence)) = content.temperature {
            self.temp_c = temp_c;
            let record = match cadence {
                TemperatureCadence::Each => true,
                // It comes with every sample: recorded once a second, as polls would be.
                TemperatureCadence::WithSamples => {
                    let due = self
                        .temp_logged_ns
                        .is_none_or(|last| t_mono_ns >= last + TEMPERATURE_LOG_INTERVAL_NS);
                    if due {
                        self.temp_logged_ns = Some(t_mono_ns);
                    }
                    due
                }
            };
            if record {
                self.counters.temperatures += 1;
                // The frame goes into the log before the temperature taken from it.
                self.flush_frame(t_mono_ns, t_wall_ns, sinks);
                sinks.log(LogRecord::Temperature {
                    t_wall_ns,
                    temp_c: self.temp_c,
                });
            }
        }
        if content.unusable {
            self.counters.undecodable += 1;
        }
        if let Some(reading) = &content.reading {
            self.on_reading(reading, t_mono_ns, t_wall_ns, sinks);
        }
        // A frame that made no sample is logged on its own.
        self.flush_frame(t_mono_ns, t_wall_ns, sinks);
    }

    /// Logs one good frame and counts it, without making a sample of it (the start-up's and the
    /// probe's bytes).
    pub fn log_frame(&mut self, frame: SampleFrame, t_mono_ns: u64, t_wall_ns: u64, sinks: &Sinks) {
        self.counters.frames += 1;
        self.hold_frame(frame);
        self.flush_frame(t_mono_ns, t_wall_ns, sinks);
    }

    /// Keeps a good frame for the sample it may make (logged with it, as one record). Every
    /// event that holds a frame flushes it before it returns, so none is held from an earlier
    /// event.
    fn hold_frame(&mut self, frame: SampleFrame) {
        debug_assert!(self.pending_frame.is_none(), "a frame held past its event");
        self.pending_frame = Some(frame);
    }

    /// Logs the held frame on its own, if a frame is held (it made no sample, or something
    /// else is logged before its sample).
    fn flush_frame(&mut self, t_mono_ns: u64, t_wall_ns: u64, sinks: &Sinks) {
        if let Some(frame) = self.pending_frame.take() {
            sinks.log(LogRecord::RawFrame {
                t_host_wall_ns: t_wall_ns,
                t_host_monotonic_ns: t_mono_ns,
                stream_offset: frame.stream_offset,
                accepted: true,
                reject_reason: None,
                bytes: frame.bytes,
            });
        }
    }

    /// The steps every device shares: gap accounting, time stamp, the raw sample, correction,
    /// health, publishing.
    pub fn on_reading(
        &mut self,
        reading: &DeviceReading,
        t_mono_ns: u64,
        t_wall_ns: u64,
        sinks: &mut Sinks,
    ) {
        let ticks_unwrapped = reading.ticks_unwrapped;
        let step = self.gaps.on_sample(
            self.seq,
            ticks_unwrapped,
            self.session.timebase.tick_period_s(),
        );
        self.counters.samples_lost += step.lost_before + step.lost_earlier;
        if step.learned {
            // Positions were whole ticks until now: their lower envelope is biased by up to
            // half a tick, so the fit starts again from exact positions.
            self.clock.restart_fit();
        }
        let t_device_ns = self.session.timebase.device_ns(ticks_unwrapped);
        let (t_sample_ns, t_sample_wall_ns) = match self.sample_clock {
            SampleClock::DeviceFit => {
                let t = self
                    .clock
                    .update(step.position_ticks, step.spacing_ticks, t_mono_ns);
                (t, self.wall.stamp(t, t_mono_ns, t_wall_ns))
            }
            SampleClock::Gnss => {
                let t = self
                    .clock
                    .update(step.position_ticks, step.spacing_ticks, t_mono_ns);
                let wall = self.wall.stamp(t, t_mono_ns, t_wall_ns);
                (t, self.gnss.stamp(t_device_ns, t, reading.gnss, wall))
            }
            // No fit to run (and none to report): frames read together share their host
            // times, so only the order is kept.
            SampleClock::Host => {
                let next = |last: Option<u64>, t: u64| {
                    last.map_or(t, |l| t.max(l.saturating_add(MIN_HOST_SPACING_NS)))
                };
                let (last_mono, last_wall) = self.last_host_stamps.unzip();
                let stamps = (next(last_mono, t_mono_ns), next(last_wall, t_wall_ns));
                self.last_host_stamps = Some(stamps);
                stamps
            }
        };
        let mut flags = match reading.counts {
            Some(c) if c.scaled => raw_flags::SCALED_COUNTS,
            Some(_) => 0,
            None => raw_flags::NO_COUNTS,
        };
        if step.lost_before > 0 {
            flags |= raw_flags::GAP_BEFORE;
        }
        if self.temp_c.is_nan() {
            flags |= raw_flags::TEMP_STALE;
        }
        if reading.saturated {
            flags |= raw_flags::SATURATED;
        }
        let counts = reading.counts.unwrap_or(Counts {
            accel: [0; 3],
            gyro: [0; 3],
            mag: [0; 3],
            scaled: false,
        });
        let m = &reading.measured;
        let raw = RawSample {
            seq: self.seq,
            t_device_ns,
            t_host_monotonic_ns: t_mono_ns,
            t_host_wall_ns: t_wall_ns,
            t_sample_ns,
            ticks_unwrapped,
            accel_counts: counts.accel,
            gyro_counts: counts.gyro,
            mag_counts: counts.mag,
            temp_c: self.temp_c,
            ticks: reading.ticks,
            command: reading.command,
            reserved: 0,
            flags,
            accel_device_m_s2: m.accel_m_s2.into(),
            gyro_device_rad_s: m.gyro_rad_s.into(),
            mag_device_gauss: m.mag_gauss.into(),
        };
        let mut corrected = self.correct(m, t_sample_ns, t_device_ns);
        corrected.t_wall_ns = t_sample_wall_ns;
        self.watch_health(&mut corrected, (t_mono_ns, t_wall_ns), sinks);
        let compensated = reading.compensated.map(|c| DeviceCompensated {
            accel_m_s2: c.accel_m_s2.into(),
            gyro_rad_s: c.gyro_rad_s.into(),
        });
        self.publish(raw, corrected, compensated, sinks);
    }

    /// Applies the calibration in force (or only the GainScales) to one sample.
    fn correct(&mut self, m: &Measured, t_sample_ns: u64, t_device_ns: u64) -> CorrectedSample {
        let mut flags = if self.session.gains.fallback.any() {
            corrected_flags::FALLBACK_GAINS
        } else {
            0
        };
        if self.temp_c.is_nan() {
            flags |= corrected_flags::TEMP_STALE;
        }
        let (accel, gyro, mag, calibration_id) = match &self.calibration {
            Some(cal) => {
                // Angular acceleration for the lever-arm term: finite difference of the last
                // two corrected rates (one sample late, which the lever-arm magnitude makes
                // negligible). Never the measured rate against a corrected one: their
                // difference is the gyro's bias and scale error, not an acceleration.
                let angular_accel = match self.last_gyro {
                    [Some((t0, w0)), Some((t1, w1))] if t1 > t0 => {
                        (w1 - w0) / ((t1 - t0) as f64 * 1e-9)
                    }
                    _ => Vector3::zeros(),
                };
                let temp = if self.temp_c.is_nan() {
                    25.0
                } else {
                    self.temp_c
                };
                let c = cal
                    .model
                    .correct(m, temp, t_device_ns as f64 * 1e-9, angular_accel);
                if !c.converged {
                    flags |= corrected_flags::NOT_CONVERGED;
                    self.counters.not_converged += 1;
                }
                // A rate the unit did not have (NaN) would make the next two samples' lever-arm
                // term NaN too: the difference skips it.
                if c.gyro_rad_s.iter().all(|v| v.is_finite()) {
                    self.last_gyro = [self.last_gyro[1], Some((t_sample_ns, c.gyro_rad_s))];
                }
                (c.accel_m_s2, c.gyro_rad_s, c.mag_gauss, cal.id)
            }
            None => {
                flags |= corrected_flags::UNCALIBRATED;
                (m.accel_m_s2, m.gyro_rad_s, m.mag_gauss, 0)
            }
        };
        CorrectedSample {
            seq: self.seq,
            t_sample_ns,
            t_wall_ns: 0,
            t_device_ns,
            accel_m_s2: accel.into(),
            gyro_rad_s: gyro.into(),
            mag_gauss: mag.into(),
            temp_c: self.temp_c,
            calibration_id,
            flags,
            reserved: 0,
        }
    }

    /// Bias tracking's offsets applied, the sample handed to the health monitor, and a report
    /// published, recorded and its state changes logged.
    /// `host_ns`: the frame's host times (monotonic, wall).
    fn watch_health(
        &mut self,
        corrected: &mut CorrectedSample,
        host_ns: (u64, u64),
        sinks: &mut Sinks,
    ) {
        let Some(monitor) = &mut self.health else {
            return;
        };
        let (accel_offset, gyro_offset) = monitor.applied_offsets();
        if accel_offset != Vector3::zeros() || gyro_offset != Vector3::zeros() {
            for i in 0..3 {
                corrected.accel_m_s2[i] -= accel_offset[i];
                corrected.gyro_rad_s[i] -= gyro_offset[i];
            }
            corrected.flags |= corrected_flags::BIAS_TRACKED;
        }
        let Some(event) = monitor.push(
            corrected.t_sample_ns,
            corrected.t_wall_ns,
            &corrected.accel_m_s2,
            &corrected.gyro_rad_s,
            corrected.temp_c,
        ) else {
            return;
        };
        // The frame goes into the log before the report that its sample closed.
        self.flush_frame(host_ns.0, host_ns.1, sinks);
        for change in &event.changes {
            if change.is_recovery() {
                info!("{change}");
            } else {
                warn!("{change}");
            }
        }
        if let Some(p) = &mut sinks.publishers {
            let sent = p.publish_health(&event.report).is_ok() & p.notify(ShmEvent::Health).is_ok();
            if !sent {
                self.counters.publish_errors += 1;
            }
        }
        if let Some(r) = &mut sinks.readers {
            r.send(&event.report);
        }
        sinks.log(LogRecord::Health(event.report));
        self.health_report = Some(event.report);
    }

    /// Counts the sample and hands it to shared memory and the log.
    /// `compensated`: the unit's own compensated reading, recorded beside the sample.
    fn publish(
        &mut self,
        raw: RawSample,
        corrected: CorrectedSample,
        compensated: Option<DeviceCompensated>,
        sinks: &mut Sinks,
    ) {
        self.rate_origin
            .get_or_insert((raw.t_sample_ns, self.counters.samples));
        self.last_sample_ns = Some(raw.t_sample_ns);
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
        if let Some(r) = &mut sinks.readers {
            r.send(&raw);
            r.send(&corrected);
        }
        // The record is built only for a sink that takes it: it is the largest thing the
        // per-frame path moves.
        if sinks.logs() {
            sinks.log(LogRecord::Sample {
                frame: self.pending_frame.take(),
                raw,
                corrected,
                compensated,
            });
        }
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
        // Health off: `unknown` (0) for both.
        let (health_accel, health_gyro) = self.health_states().unwrap_or_default();
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
                + sinks
                    .readers
                    .as_ref()
                    .map_or(0, readers::ReadersServer::drops)
                + self.counters.publish_errors,
            reconnects,
            calibration_id: self.calibration.as_ref().map_or(0, |c| c.id),
            tick_period_est_s: self.clock.tick_period_s().unwrap_or(f64::NAN),
            clock_drift_ppm: self.clock.drift_ppm().unwrap_or(f64::NAN),
            temp_c: self.temp_c,
            device_connected: u8::from(connected),
            logging: u8::from(logging),
            gains_fallback: self.session.gains.fallback.mask(),
            health_accel: health_accel.code(),
            health_gyro: health_gyro.code(),
            protocol: self.session.status_protocol,
            configuration_unverified: u8::from(!self.session.configuration_verified),
            reserved: 0,
            clock_offset_s: self.clock.offset_s().unwrap_or(f64::NAN),
            clock_residual_s: self.clock.residual_s().unwrap_or(f64::NAN),
            gain_scale_accel: self.session.gains.accel,
            gain_scale_gyro: self.session.gains.gyro,
            gain_scale_mag: self.session.gains.mag,
            reserved_end: [0; 2],
            packets_unusable: self.counters.undecodable,
            fields_skipped: self.counters.fields_skipped,
            time_source: self.time_source().code(),
            time_sync: self.time_sync(),
            reserved_sync: [0; 6],
            gnss_minus_wall_s: self.gnss.minus_wall_s().unwrap_or(f64::NAN),
            gnss_drift_ppm: self.gnss.drift_ppm().unwrap_or(f64::NAN),
            gnss_valid_transitions: self.gnss.transitions().0,
            gnss_lost_transitions: self.gnss.transitions().1,
        }
    }

    /// The `device.time-source` the stamps follow.
    pub fn time_source(&self) -> TimeSource {
        match self.sample_clock {
            SampleClock::DeviceFit => TimeSource::Device,
            SampleClock::Host => TimeSource::Host,
            SampleClock::Gnss => TimeSource::Gnss,
        }
    }

    /// How the stamps stand against their source ([`imu_bus::sample::time_sync`] code).
    pub fn time_sync(&self) -> u8 {
        use imu_bus::sample::time_sync;
        let fitted = self.clock.drift_ppm().is_some();
        match self.sample_clock {
            SampleClock::Host => time_sync::NONE,
            SampleClock::DeviceFit if fitted => time_sync::DEVICE_FIT,
            SampleClock::DeviceFit => time_sync::NONE,
            SampleClock::Gnss => match self.gnss.state() {
                // No GNSS time yet: the stamps are the device fit's.
                crate::clock::GnssState::None if fitted => time_sync::DEVICE_FIT,
                s => s.code(),
            },
        }
    }
}

/// Logs bytes the decoder rejected (every codec's decoder shares the reasons).
pub fn log_rejected(
    bytes: Vec<u8>,
    offset: u64,
    reason: RejectReason,
    t_mono_ns: u64,
    t_wall_ns: u64,
    sinks: &Sinks,
) {
    sinks.log(LogRecord::RawFrame {
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
        bytes: FrameData::from_vec(bytes),
    });
}
