//! Loading and validating a plan file into its expected segments.

use super::*;

impl Plan {
    /// Reads and validates a plan file.
    pub fn load(path: &Path) -> Result<Plan, PlanError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| PlanError::Io {
            file: file.clone(),
            source,
        })?;
        Plan::from_toml_str(&text, &file)
    }

    /// Parses and validates plan text; `file` names it in messages.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Plan, PlanError> {
        let raw: PlanFile = toml::from_str(text).map_err(|e| parse_error(file, text, &e))?;
        let at = PlanText { file, text };
        at.check_format_and_latitude(&raw)?;
        let height_m = raw.height_m.unwrap_or(0.0);
        if !height_m.is_finite() || height_m.abs() > 20_000.0 {
            return Err(at.invalid(
                "height-m",
                "height-m",
                format!("{height_m} m is not a height above the ellipsoid"),
            ));
        }
        let (gravity_m_s2, gravity_source) = at.gravity(&raw, height_m)?;
        let direction_tolerance_deg = at.positive_or(
            raw.direction_tolerance_deg,
            "direction-tolerance-deg",
            DEFAULT_DIRECTION_TOLERANCE_DEG,
        )?;
        let rate_tolerance_percent = at.positive_or(
            raw.rate_tolerance_percent,
            "rate-tolerance-percent",
            DEFAULT_RATE_TOLERANCE_PERCENT,
        )?;
        let powered_on_before_s = raw.powered_on_before_s.unwrap_or(0.0);
        if !(powered_on_before_s.is_finite() && powered_on_before_s >= 0.0) {
            return Err(at.invalid(
                "powered-on-before-s",
                "powered-on-before-s",
                "must be 0 or more seconds".into(),
            ));
        }
        at.check_temperature_and_steps(&raw)?;
        let any_explicit = raw.steps.iter().position(StepFile::has_windows);
        let mut entries = Vec::new();
        for (i, step) in raw.steps.iter().enumerate() {
            expand_step(file, text, i, step, any_explicit, &mut entries)?;
        }
        Ok(Plan {
            file: file.to_string(),
            name: raw.name,
            description: raw.description,
            latitude_deg: raw.latitude_deg,
            gravity_m_s2,
            gravity_source,
            powered_on_before_s,
            temp_c: raw.temp_c,
            direction_tolerance_deg,
            rate_tolerance_percent,
            entries,
        })
    }
}

/// The plan's text and file name, for the errors of its validation.
struct PlanText<'a> {
    file: &'a str,
    text: &'a str,
}

impl PlanText<'_> {
    /// `message` about the value of `key` (its line in the file), under `context`.
    fn invalid(&self, key: &str, context: &str, message: String) -> PlanError {
        PlanError::Invalid {
            file: self.file.to_string(),
            line: imu_model::line_of_key(self.text, key),
            context: context.to_string(),
            message,
        }
    }

    fn check_format_and_latitude(&self, raw: &PlanFile) -> Result<(), PlanError> {
        if raw.format != PLAN_FORMAT {
            return Err(self.invalid(
                "format",
                "format",
                format!(
                    "`{}` is not a plan format this version reads; write format = \"{PLAN_FORMAT}\"",
                    raw.format
                ),
            ));
        }
        if let Some(l) = raw.latitude_deg
            && !(-90.0..=90.0).contains(&l)
        {
            return Err(self.invalid(
                "latitude-deg",
                "latitude-deg",
                format!("{l} is outside -90..90 degrees"),
            ));
        }
        Ok(())
    }

    /// Gravity, m/s^2, and where it comes from: given, or the normal gravity at the plan's
    /// latitude and `height_m`.
    fn gravity(&self, raw: &PlanFile, height_m: f64) -> Result<(f64, String), PlanError> {
        match (raw.gravity_m_s2, raw.latitude_deg) {
            (Some(g), _) => {
                if !(9.7..=9.9).contains(&g) {
                    return Err(self.invalid(
                        "gravity-m-s2",
                        "gravity-m-s2",
                        format!("{g} m/s^2 is not a gravity on Earth's surface (9.78..9.83)"),
                    ));
                }
                Ok((g, format!("{g} m/s^2 (given in the plan)")))
            }
            (None, Some(lat)) => {
                let g = normal_gravity_m_s2(lat, height_m);
                Ok((
                    g,
                    format!(
                        "{g:.5} m/s^2 (WGS-84 normal gravity at latitude {lat} deg, height {height_m} m)"
                    ),
                ))
            }
            (None, None) => Err(self.invalid(
                "format",
                "gravity",
                "give latitude-deg (gravity then follows from WGS-84 normal gravity, and \
                 Earth's rate from the latitude) or gravity-m-s2"
                    .into(),
            )),
        }
    }

    /// The value of `key`, `default` when not given, which must be positive.
    fn positive_or(&self, v: Option<f64>, key: &str, default: f64) -> Result<f64, PlanError> {
        let x = v.unwrap_or(default);
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(self.invalid(key, key, format!("{x} must be positive")))
        }
    }

    fn check_temperature_and_steps(&self, raw: &PlanFile) -> Result<(), PlanError> {
        if let Some(t) = raw.temp_c
            && !(-60.0..=150.0).contains(&t)
        {
            return Err(self.invalid(
                "temp-c",
                "temp-c",
                format!("{t} deg C is not a sensor temperature"),
            ));
        }
        if raw.steps.is_empty() {
            return Err(self.invalid(
                "format",
                "step",
                "a plan needs at least one [[step]]".into(),
            ));
        }
        if raw.steps.iter().all(|s| s.kind == StepKind::Skip) {
            return Err(self.invalid(
                "format",
                "step",
                "every step is a skip: a plan needs at least one segment to fit".into(),
            ));
        }
        Ok(())
    }
}
