//! Checking a parsed scenario: every value in range, every segment well formed, with errors
//! that name the file, the segment and the key.

use super::*;

/// Builds the error of one failed check.
type Invalid<'a> = &'a dyn Fn(String, String) -> ScenarioError;

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

impl Scenario {
    pub(super) fn validate(&self, file: &str) -> Result<(), ScenarioError> {
        let invalid = |context: String, message: String| ScenarioError::Invalid {
            file: file.to_string(),
            context,
            message,
        };
        self.validate_environment(&invalid)?;
        self.validate_device(&invalid)?;
        self.validate_temperature(&invalid)?;
        self.validate_hand(&invalid)?;
        self.validate_segments(&invalid)
    }

    /// Tremor and tilt noise: small angles, a tremor band the data rate can carry.
    fn validate_hand(&self, invalid: Invalid<'_>) -> Result<(), ScenarioError> {
        let h = &self.hand;
        if !(h.tremor_deg.is_finite() && (0.0..=5.0).contains(&h.tremor_deg)) {
            return Err(invalid(
                "hand.tremor-deg".into(),
                format!(
                    "{} must be an RMS angle of 0 to 5 degrees (a hand's tremor: ~0.05-0.5)",
                    h.tremor_deg
                ),
            ));
        }
        let [lo, hi] = h.tremor_band_hz;
        if h.tremor_deg > 0.0 && !(positive(lo) && lo < hi && hi <= self.rate_hz / 2.0) {
            return Err(invalid(
                "hand.tremor-band-hz".into(),
                format!(
                    "[{lo}, {hi}] must be 0 < low < high <= half the data rate ({} Hz)",
                    self.rate_hz / 2.0
                ),
            ));
        }
        if !(h.tilt_noise_deg.is_finite() && (0.0..=30.0).contains(&h.tilt_noise_deg)) {
            return Err(invalid(
                "hand.tilt-noise-deg".into(),
                format!("{} must be 0 to 30 degrees", h.tilt_noise_deg),
            ));
        }
        Ok(())
    }

    /// Disturbances, data rate, latitude, gravity and transitions.
    fn validate_environment(&self, invalid: Invalid<'_>) -> Result<(), ScenarioError> {
        for (i, d) in self.disturbances.iter().enumerate() {
            let time_ok = match d.shape {
                super::DisturbanceShape::Sine {
                    frequency_hz,
                    phase_deg,
                } => positive(frequency_hz) && phase_deg.is_finite(),
                super::DisturbanceShape::Step { at_s } => at_s.is_finite() && at_s >= 0.0,
            };
            if !time_ok || d.amplitude.iter().any(|a| !a.is_finite()) {
                return Err(invalid(
                    format!("disturbance[{i}]"),
                    "frequency-hz must be positive, step-at-s >= 0 and the amplitudes finite"
                        .into(),
                ));
            }
        }
        if !positive(self.rate_hz) || self.rate_hz > 100_000.0 {
            return Err(invalid(
                "rate-hz".into(),
                format!(
                    "{} Hz is not a usable data rate (0 < rate <= 100000)",
                    self.rate_hz
                ),
            ));
        }
        if !(-90.0..=90.0).contains(&self.latitude_deg) {
            return Err(invalid(
                "latitude-deg".into(),
                format!("{} is outside -90..90 degrees", self.latitude_deg),
            ));
        }
        if !positive(self.gravity_m_s2) || !positive(self.transition_s) {
            return Err(invalid(
                "gravity-m-s2 / transition-s".into(),
                "must be positive".into(),
            ));
        }
        Ok(())
    }

    /// The device's clock, GainScales and, for MIP and VectorNav, a rate its base rate divides
    /// into.
    fn validate_device(&self, invalid: Invalid<'_>) -> Result<(), ScenarioError> {
        if !positive(self.device.tick_period_s) {
            return Err(invalid(
                "device.tick-period-s".into(),
                "must be positive (6.5536e-3 on most units)".into(),
            ));
        }
        if self.device.clock_drift_ppm.abs() >= 1e5 {
            return Err(invalid(
                "device.clock-drift-ppm".into(),
                "must be well under 1e5 ppm".into(),
            ));
        }
        let d = &self.device;
        if !(d.gnss_epoch_utc_s.is_finite()
            && d.gnss_epoch_utc_s >= imu_proto::gnss_time::GPS_EPOCH_UNIX_S as f64)
        {
            return Err(invalid(
                "device.gnss-epoch-utc-s".into(),
                "must be a UTC time after the GPS epoch (1980-01-06), s since 1970".into(),
            ));
        }
        if let Some(o) = d
            .gnss_outage
            .iter()
            .find(|o| !(o.start_s.is_finite() && o.end_s.is_finite() && o.start_s < o.end_s))
        {
            return Err(invalid(
                "device.gnss-outage".into(),
                format!("start-s {} must come before end-s {}", o.start_s, o.end_s),
            ));
        }
        let g = self.device.gain_scale;
        if g.accel == 0 || g.gyro == 0 || g.mag == 0 {
            return Err(invalid(
                "device.gain-scale".into(),
                "GainScale words must be non-zero".into(),
            ));
        }
        if self.device.protocol == DeviceProtocol::Xsens
            && (self.rate_hz > XSENS_MAX_RATE_HZ || self.rate_hz.fract() != 0.0)
        {
            return Err(invalid(
                "rate-hz".into(),
                format!(
                    "{} Hz is not an Xsens output rate: the simulated MTi streams a whole number \
                     of Hz up to {} Hz",
                    self.rate_hz, XSENS_MAX_RATE_HZ
                ),
            ));
        }
        if self.device.protocol == DeviceProtocol::Mip {
            let decimation = MIP_IMU_BASE_RATE_HZ / self.rate_hz;
            if self.rate_hz > MIP_IMU_BASE_RATE_HZ || (decimation - decimation.round()).abs() > 1e-9
            {
                return Err(invalid(
                    "rate-hz".into(),
                    format!(
                        "{} Hz is not a MIP data rate: the simulated device's base rate is {} Hz, \
                         so the rate must be {} Hz divided by a whole number",
                        self.rate_hz, MIP_IMU_BASE_RATE_HZ, MIP_IMU_BASE_RATE_HZ
                    ),
                ));
            }
        }
        if self.device.protocol == DeviceProtocol::Vectornav {
            let imu_hz = f64::from(imu_proto::vectornav::IMU_RATE_HZ);
            let divisor = imu_hz / self.rate_hz;
            if self.rate_hz > imu_hz || (divisor - divisor.round()).abs() > 1e-9 {
                return Err(invalid(
                    "rate-hz".into(),
                    format!(
                        "{} Hz is not a VectorNav output rate: the unit's IMU rate is {imu_hz} Hz, \
                         so the rate must be {imu_hz} Hz divided by a whole number",
                        self.rate_hz
                    ),
                ));
            }
            let m = &self.device.model;
            if !m.is_empty()
                && !m
                    .bytes()
                    .all(|b| b.is_ascii_graphic() && !b",*$".contains(&b))
            {
                return Err(invalid(
                    "device.model".into(),
                    "a model name is printable ASCII without ',', '*' or '$' (it is sent in \
                     a register reply)"
                        .into(),
                ));
            }
        }
        Ok(())
    }

    /// The temperature profile's parameters.
    fn validate_temperature(&self, invalid: Invalid<'_>) -> Result<(), ScenarioError> {
        match &self.temperature {
            TemperatureProfile::Warmup { tau_s, .. } if !positive(*tau_s) => {
                return Err(invalid(
                    "temperature".into(),
                    "tau-s must be positive".into(),
                ));
            }
            TemperatureProfile::Cycle { period_s, .. } if !positive(*period_s) => {
                return Err(invalid(
                    "temperature".into(),
                    "period-s must be positive".into(),
                ));
            }
            TemperatureProfile::Points { points }
                if points.is_empty() || points.windows(2).any(|w| w[1][0] <= w[0][0]) =>
            {
                return Err(invalid(
                    "temperature".into(),
                    "points need at least one [time-s, temp-c] pair, in strictly increasing time"
                        .into(),
                ));
            }
            _ => {}
        }
        Ok(())
    }

    /// At least one segment; only the last may run forever; each one well formed.
    fn validate_segments(&self, invalid: Invalid<'_>) -> Result<(), ScenarioError> {
        if self.segments.is_empty() {
            return Err(invalid(
                "segment".into(),
                "a scenario needs at least one [[segment]]".into(),
            ));
        }
        let last = self.segments.len() - 1;
        for (i, seg) in self.segments.iter().enumerate() {
            let ctx = format!("segment {} ({})", i + 1, seg.kind_name());
            validate_segment(seg, i == last, &ctx, invalid)?;
        }
        Ok(())
    }
}

/// A static segment's keys (`is_last`: it may omit its duration).
fn validate_static(
    orientation: Option<&OrientationSpec>,
    duration_s: Option<f64>,
    move_s: Option<f64>,
    is_last: bool,
    ctx: &str,
    invalid: Invalid<'_>,
) -> Result<(), ScenarioError> {
    let bad = |m: &str| Err(invalid(ctx.to_string(), m.to_string()));
    if let Some(o) = orientation {
        o.enu_from_sensor()
            .map_err(|m| invalid(ctx.to_string(), m))?;
    }
    match duration_s {
        None if !is_last => {
            return bad("only the last segment may omit duration-s (it then runs forever)");
        }
        Some(d) if !positive(d) => return bad("duration-s must be positive"),
        _ => {}
    }
    if move_s.is_some_and(|m| !positive(m)) {
        return bad("move-s must be positive");
    }
    Ok(())
}

/// One segment's keys (`is_last`: it may omit its duration). A flat list of checks, one arm per
/// segment kind, which is why it is long.
fn validate_segment(
    seg: &SegmentSpec,
    is_last: bool,
    ctx: &str,
    invalid: Invalid<'_>,
) -> Result<(), ScenarioError> {
    let bad = |m: &str| Err(invalid(ctx.to_string(), m.to_string()));
    match seg {
        SegmentSpec::Static {
            orientation,
            duration_s,
            move_s,
            ..
        } => validate_static(
            orientation.as_ref(),
            *duration_s,
            *move_s,
            is_last,
            ctx,
            invalid,
        )?,
        SegmentSpec::IndexTable {
            step_deg,
            positions,
            dwell_s,
            move_s,
            ..
        } => {
            if *positions == 0 || !positive(*dwell_s) || !positive(*move_s) || !step_deg.is_finite()
            {
                return bad("positions, dwell-s and move-s must be positive and step-deg finite");
            }
        }
        SegmentSpec::RateSteps {
            rates_deg_s,
            dwell_s,
            accel_deg_s2,
            ..
        } => {
            if rates_deg_s.is_empty()
                || !positive(*dwell_s)
                || !positive(*accel_deg_s2)
                || rates_deg_s.iter().any(|r| !r.is_finite())
            {
                return bad(
                    "rates-deg-s must be a non-empty list; dwell-s and accel-deg-s2 positive",
                );
            }
        }
        SegmentSpec::Rotate {
            angle_deg,
            duration_s,
            wobble_deg,
            ..
        } => {
            if !angle_deg.is_finite() || !positive(*duration_s) {
                return bad("angle-deg must be finite and duration-s positive");
            }
            if !(0.0..45.0).contains(wobble_deg) {
                return bad("wobble-deg must be at least 0 and below 45 (degrees)");
            }
        }
        SegmentSpec::Impacts {
            count,
            period_s,
            peak_g,
            width_ms,
            ..
        } => {
            if *count == 0
                || !positive(*period_s)
                || !peak_g.is_finite()
                || !positive(*width_ms)
                || width_ms * 1e-3 >= *period_s
            {
                return bad(
                    "count, period-s and width-ms must be positive, and each shock shorter than the period",
                );
            }
        }
        SegmentSpec::RandomPoses {
            count,
            dwell_s,
            move_s,
        } => {
            if *count == 0 || !positive(*dwell_s) || !positive(*move_s) {
                return bad("count, dwell-s and move-s must be positive");
            }
        }
    }
    Ok(())
}
