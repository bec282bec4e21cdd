//! Live calibration health: the calibration in force held against physics whenever the unit is
//! still (issue: "the daemon holds its calibration against physics").
//!
//! The detector, the references, the sequential tests, their states and the offset estimators
//! are `imu_analysis::health` (one home: `imu-analyze health` and `imud.health_check` run the
//! same offline). Here: the `[health]` configuration mapped to its options, the calibration in
//! force handed over, each window's result as the bus's `CalibrationHealth` (published,
//! recorded), the state changes as typed `HealthChange`s (logged), and bias tracking: with
//! `track-bias`, a stale triad's offset is applied to the corrected stream (bounded by
//! `track-bias-max-*`), logged and recorded, never silently.

use imu_analysis::health::{Monitor, NoiseSource, WindowCheck};
use imu_bus::CalibrationHealth;
use imu_bus::sample::{HealthState, health_checks, health_noise_source};
use imu_model::Vec3;

use crate::config::HealthConfig;
use crate::pipeline::ActiveCalibration;

/// A health report and the changes it brought.
#[derive(Debug, Clone, PartialEq)]
pub struct HealthEvent {
    /// The report (also published and recorded).
    pub report: CalibrationHealth,
    /// The state changes and bias-tracking steps of this window, in order (the daemon logs
    /// each one's `Display`).
    pub changes: Vec<HealthChange>,
}

/// The triad a [`HealthChange`] concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HealthTriad {
    /// The accelerometers.
    Accel,
    /// The gyroscopes.
    Gyro,
}

impl HealthTriad {
    /// `accel` or `gyro`.
    pub fn name(self) -> &'static str {
        match self {
            HealthTriad::Accel => "accel",
            HealthTriad::Gyro => "gyro",
        }
    }
}

/// One change the health monitor made: programs match on the variant (or its
/// [`code`](Self::code)); the log line is its `Display`.
#[derive(Debug, Clone, PartialEq)]
pub enum HealthChange {
    /// A triad's state changed.
    State {
        /// Which triad.
        triad: HealthTriad,
        /// The state before.
        from: HealthState,
        /// The state now.
        to: HealthState,
        /// The p-value of the window that decided it.
        p: f64,
        /// The report at the change (residuals, offsets, temperature, still-window count).
        report: CalibrationHealth,
        /// The calibration's temperature range, when the report's temperature lies outside it.
        outside_range_c: Option<[f64; 2]>,
    },
    /// Bias tracking applied a step to a stale triad's correction.
    BiasTracking {
        /// Which triad.
        triad: HealthTriad,
        /// The step applied now (m/s^2 or rad/s).
        step: Vec3,
        /// The total applied offset after it, bounded by `bound`.
        total: Vec3,
        /// The bound of the total's norm.
        bound: f64,
    },
}

impl HealthChange {
    /// The stable code: `state_change` or `bias_tracking`.
    pub fn code(&self) -> &'static str {
        match self {
            HealthChange::State { .. } => "state_change",
            HealthChange::BiasTracking { .. } => "bias_tracking",
        }
    }

    /// True for a return to `ok` (logged as information; every other change is a warning).
    pub fn is_recovery(&self) -> bool {
        matches!(
            self,
            HealthChange::State {
                to: HealthState::Ok,
                ..
            }
        )
    }
}

impl std::fmt::Display for HealthChange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HealthChange::State {
                triad,
                from,
                to,
                p,
                report,
                outside_range_c,
            } => {
                f.write_str(&change_line(*triad, *from, *to, *p, report))?;
                if let Some([lo, hi]) = outside_range_c {
                    write!(
                        f,
                        "; the temperature {:.1} C is outside the calibration's range \
                         {lo:.1} to {hi:.1} C (a thermal effect it never saw?)",
                        report.temp_c
                    )?;
                }
                Ok(())
            }
            HealthChange::BiasTracking {
                triad: HealthTriad::Accel,
                step,
                total,
                bound,
            } => write!(
                f,
                "health: accel bias tracking applies {} m/s^2 (total {}, bound {bound:.3})",
                fmt_vec(*step),
                fmt_vec(*total)
            ),
            HealthChange::BiasTracking {
                triad: HealthTriad::Gyro,
                step,
                total,
                bound,
            } => write!(
                f,
                "health: gyro bias tracking applies {} rad/s (total {}, bound {bound:.4})",
                fmt_vec(*step),
                fmt_vec(*total)
            ),
        }
    }
}

/// The live health monitor of one calibration.
#[derive(Debug, Clone)]
pub struct HealthMonitor {
    config: HealthConfig,
    monitor: Monitor,
    calibration_id: u64,
    /// The temperatures the calibration's data covered, deg C.
    temperature_range_c: Option<[f64; 2]>,
    /// Bias offsets applied to the corrected stream (bias tracking), m/s^2 and rad/s.
    applied_accel_m_s2: Vec3,
    applied_gyro_rad_s: Vec3,
}

impl HealthMonitor {
    /// A monitor of `calibration` (none: the stream is reported as uncalibrated).
    pub fn new(config: &HealthConfig, calibration: Option<&ActiveCalibration>) -> HealthMonitor {
        HealthMonitor {
            config: config.clone(),
            monitor: Monitor::new(
                &config.check_options(),
                calibration.map(|c| &*c.model),
                calibration.is_some(),
            ),
            calibration_id: calibration.map_or(0, |c| c.id),
            temperature_range_c: calibration.and_then(|c| c.model.provenance.temperature_range_c),
            applied_accel_m_s2: Vec3::zeros(),
            applied_gyro_rad_s: Vec3::zeros(),
        }
    }

    /// The stream was interrupted (a new device session): the current still run is dropped.
    pub fn interrupt(&mut self) {
        self.monitor.interrupt();
    }

    /// Bias offsets applied to the corrected stream by bias tracking (accel m/s^2, gyro rad/s);
    /// zero unless `track-bias` is on and a triad went stale.
    pub fn applied_offsets(&self) -> (Vec3, Vec3) {
        (self.applied_accel_m_s2, self.applied_gyro_rad_s)
    }

    /// The states (accel, gyro).
    pub fn states(&self) -> (HealthState, HealthState) {
        self.monitor.states()
    }

    /// One corrected sample (after bias tracking); returns a report when a still window closed.
    pub fn push(
        &mut self,
        t_sample_ns: u64,
        t_wall_ns: u64,
        accel_m_s2: &[f64; 3],
        gyro_rad_s: &[f64; 3],
        temp_c: f64,
    ) -> Option<HealthEvent> {
        let check = self
            .monitor
            .push(t_sample_ns, accel_m_s2, gyro_rad_s, temp_c)?;
        Some(self.on_window(&check, t_wall_ns))
    }

    /// A window's result as the report, its state changes and bias tracking.
    fn on_window(&mut self, c: &WindowCheck, t_wall_ns: u64) -> HealthEvent {
        let mut report = self.blank_report(c, t_wall_ns);
        let mut changes = Vec::new();
        let Some(r) = &c.residuals else {
            return HealthEvent { report, changes };
        };
        report.accel_residual_m_s2 = r.accel_residual_m_s2;
        report.accel_expected_std_m_s2 = r.accel_var.sqrt();
        report.gyro_residual_rad_s = r.gyro_magnitude_residual_rad_s;
        report.gyro_vertical_residual_rad_s = r.gyro_vertical_residual_rad_s;
        report.gyro_expected_std_rad_s = (r.gyro_var.iter().sum::<f64>() / 3.0).sqrt();
        report.checks = health_checks::EARTH_RATE
            | if c.gravity_learned {
                health_checks::GRAVITY_LEARNED
            } else {
                health_checks::GRAVITY
            }
            | if self.config.latitude_deg.is_some() {
                health_checks::EARTH_RATE_VERTICAL
            } else {
                0
            };
        if let Some([lo, hi]) = self.temperature_range_c
            && (c.window.temp_c < lo || c.window.temp_c > hi)
        {
            report.checks |= health_checks::TEMP_OUT_OF_RANGE;
        }
        let Some(t) = c.test else {
            return HealthEvent { report, changes };
        };
        // The report as each triad's change saw it: the accel's before the gyro's was filled.
        report.accel_p = t.accel_p;
        report.accel_offset_m_s2 = t.accel_offset_m_s2.into();
        if t.accel_offset_3d {
            report.checks |= health_checks::ACCEL_BIAS_3D;
        }
        if c.states.0 != t.before.0 {
            changes.push(self.state_change(
                HealthTriad::Accel,
                t.before.0,
                c.states.0,
                t.accel_p,
                &report,
            ));
        }
        report.gyro_p = t.gyro_p;
        report.gyro_offset_rad_s = t.gyro_offset_rad_s.into();
        if c.states.1 != t.before.1 {
            changes.push(self.state_change(
                HealthTriad::Gyro,
                t.before.1,
                c.states.1,
                t.gyro_p,
                &report,
            ));
        }
        if self.config.track_bias {
            self.track(&report, &mut changes);
        }
        let (accel, gyro) = self.monitor.states();
        report.accel_state = accel.code();
        report.gyro_state = gyro.code();
        report.bias_tracking = u8::from(
            self.applied_accel_m_s2 != Vec3::zeros() || self.applied_gyro_rad_s != Vec3::zeros(),
        );
        HealthEvent { report, changes }
    }

    fn blank_report(&self, c: &WindowCheck, t_wall_ns: u64) -> CalibrationHealth {
        let nan3 = [f64::NAN; 3];
        let w = &c.window;
        // The states before the window's tests (a change's report carries them).
        let (accel_state, gyro_state) = c.test.map_or(c.states, |t| t.before);
        CalibrationHealth {
            t_sample_ns: w.end_ns.min(c.closed_ns),
            t_wall_ns,
            window_start_ns: w.start_ns,
            calibration_id: self.calibration_id,
            still_windows: c.still_windows,
            plateaus_skipped: c.plateaus,
            accel_residual_m_s2: f64::NAN,
            accel_expected_std_m_s2: f64::NAN,
            accel_p: f64::NAN,
            accel_offset_m_s2: nan3,
            gyro_residual_rad_s: f64::NAN,
            gyro_vertical_residual_rad_s: f64::NAN,
            gyro_expected_std_rad_s: f64::NAN,
            gyro_p: f64::NAN,
            gyro_offset_rad_s: nan3,
            gravity_m_s2: c.gravity_m_s2,
            temp_c: w.temp_c,
            accel_state: accel_state.code(),
            gyro_state: gyro_state.code(),
            checks: 0,
            noise_source: match c.noise_source {
                NoiseSource::Tables => health_noise_source::TABLES,
                NoiseSource::Estimated => health_noise_source::ESTIMATED,
                NoiseSource::None => health_noise_source::NONE,
            },
            bias_tracking: 0,
            reserved: [0; 3],
        }
    }

    /// A state change, with the calibration's temperature range when the report's temperature
    /// lies outside it.
    fn state_change(
        &self,
        triad: HealthTriad,
        from: HealthState,
        to: HealthState,
        p: f64,
        report: &CalibrationHealth,
    ) -> HealthChange {
        HealthChange::State {
            triad,
            from,
            to,
            p,
            report: *report,
            outside_range_c: self
                .temperature_range_c
                .filter(|_| report.checks & health_checks::TEMP_OUT_OF_RANGE != 0),
        }
    }

    /// Bias tracking: a stale triad's estimated offset is added to the applied correction
    /// (bounded), and the triad is tested afresh against the corrected stream.
    fn track(&mut self, report: &CalibrationHealth, log: &mut Vec<HealthChange>) {
        let max_a = self.config.track_bias_max_m_s2;
        let max_g = self.config.track_bias_max_rad_s;
        let (accel, gyro) = self.monitor.states();
        if accel == HealthState::Stale {
            let step = Vec3::from(report.accel_offset_m_s2);
            if step.iter().all(|v| v.is_finite()) {
                let applied = clamp_norm(self.applied_accel_m_s2 + step, max_a);
                log.push(HealthChange::BiasTracking {
                    triad: HealthTriad::Accel,
                    step,
                    total: applied,
                    bound: max_a,
                });
                self.applied_accel_m_s2 = applied;
                self.monitor.restart_accel();
            }
        }
        if gyro == HealthState::Stale {
            let step = Vec3::from(report.gyro_offset_rad_s);
            if step.iter().all(|v| v.is_finite()) {
                let applied = clamp_norm(self.applied_gyro_rad_s + step, max_g);
                log.push(HealthChange::BiasTracking {
                    triad: HealthTriad::Gyro,
                    step,
                    total: applied,
                    bound: max_g,
                });
                self.applied_gyro_rad_s = applied;
                self.monitor.restart_gyro();
            }
        }
    }
}

fn clamp_norm(v: Vec3, max: f64) -> Vec3 {
    let n = v.norm();
    if n > max { v * (max / n) } else { v }
}

fn fmt_vec(v: Vec3) -> String {
    format!("[{:+.3e}, {:+.3e}, {:+.3e}]", v[0], v[1], v[2])
}

/// The axis a vector mostly lies along, as `+x` .. `-z`.
fn dominant_axis(v: Vec3) -> String {
    let i = v.iamax();
    format!(
        "{}{}",
        if v[i] >= 0.0 { '+' } else { '-' },
        ['x', 'y', 'z'][i]
    )
}

/// The log line of a state change, with the offset that would explain it.
fn change_line(
    triad: HealthTriad,
    before: HealthState,
    after: HealthState,
    p: f64,
    r: &CalibrationHealth,
) -> String {
    let what = match triad {
        HealthTriad::Accel => {
            let o = Vec3::from(r.accel_offset_m_s2);
            format!(
                "|f| - g = {:+.4} m/s^2 (expected scatter {:.4}); accel bias shift ~ {:.4} m/s^2 along {} {}",
                r.accel_residual_m_s2,
                r.accel_expected_std_m_s2,
                o.norm(),
                dominant_axis(o),
                fmt_vec(o)
            )
        }
        HealthTriad::Gyro => {
            let o = Vec3::from(r.gyro_offset_rad_s);
            format!(
                "|w| - |Omega| = {:+.2e} rad/s (expected scatter {:.2e} per axis); gyro bias shift ~ {:.2e} rad/s ({:.3} deg/s) along {} {}",
                r.gyro_residual_rad_s,
                r.gyro_expected_std_rad_s,
                o.norm(),
                o.norm().to_degrees(),
                dominant_axis(o),
                fmt_vec(o)
            )
        }
    };
    format!(
        "health: {} {} -> {} (p {p:.1e} over still window {}): {what}",
        triad.name(),
        before.name(),
        after.name(),
        r.still_windows
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> CalibrationHealth {
        CalibrationHealth {
            still_windows: 12,
            accel_residual_m_s2: 0.02,
            accel_expected_std_m_s2: 0.001,
            accel_offset_m_s2: [0.0, 0.0, 0.02],
            temp_c: 61.5,
            ..CalibrationHealth::default()
        }
    }

    /// The log level follows the typed target state, never the words of the line.
    #[test]
    fn only_a_return_to_ok_is_a_recovery() {
        let change = |from, to| HealthChange::State {
            triad: HealthTriad::Accel,
            from,
            to,
            p: 1e-6,
            report: report(),
            outside_range_c: None,
        };
        assert!(change(HealthState::Degraded, HealthState::Ok).is_recovery());
        assert!(change(HealthState::Stale, HealthState::Ok).is_recovery());
        assert!(!change(HealthState::Ok, HealthState::Degraded).is_recovery());
        assert!(!change(HealthState::Degraded, HealthState::Stale).is_recovery());
        let tracking = HealthChange::BiasTracking {
            triad: HealthTriad::Gyro,
            step: Vec3::new(1e-4, 0.0, 0.0),
            total: Vec3::new(1e-4, 0.0, 0.0),
            bound: 0.01,
        };
        assert!(!tracking.is_recovery());
        assert_eq!(tracking.code(), "bias_tracking");
        assert_eq!(
            change(HealthState::Ok, HealthState::Degraded).code(),
            "state_change"
        );
    }

    /// The log line is the Display of the typed change: the states, the still window, the
    /// offset's axis and, out of the calibrated range, the temperature.
    #[test]
    fn a_state_change_renders_its_log_line() {
        let c = HealthChange::State {
            triad: HealthTriad::Accel,
            from: HealthState::Ok,
            to: HealthState::Degraded,
            p: 1e-6,
            report: report(),
            outside_range_c: Some([15.0, 35.0]),
        };
        let line = c.to_string();
        assert!(
            line.starts_with("health: accel ok -> degraded (p 1.0e-6 over still window 12): "),
            "{line}"
        );
        assert!(
            line.ends_with(
                "; the temperature 61.5 C is outside the calibration's range 15.0 to 35.0 C \
                 (a thermal effect it never saw?)"
            ),
            "{line}"
        );
        let tracking = HealthChange::BiasTracking {
            triad: HealthTriad::Accel,
            step: Vec3::new(0.0, 0.0, 0.02),
            total: Vec3::new(0.0, 0.0, 0.02),
            bound: 0.5,
        };
        assert_eq!(
            tracking.to_string(),
            "health: accel bias tracking applies [+0.000e0, +0.000e0, +2.000e-2] m/s^2 (total \
             [+0.000e0, +0.000e0, +2.000e-2], bound 0.500)"
        );
    }
}
