//! A whole-IMU calibration (accel, gyro and mag models plus provenance): the TOML file format,
//! the forward model for a sample, and the exact correction the daemon applies.

use crate::effect::InvalidParam;
use crate::error::{ModelError, Seg, line_of_path, parse_error, parse_path};
use crate::prepared::{InversePath, PreparedInverse};
use crate::{Conditions, Corrected, EffectKind, Measured, Triad, TriadModel, TrueMotion, Vec3};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;
use std::sync::OnceLock;

/// The value of `format` this crate reads and writes.
pub const CALIBRATION_FORMAT: &str = "imud-calibration/1";

/// File name used in errors for models that did not come from a file.
pub const IN_MEMORY: &str = "<memory>";

/// Iteration budget of the accel/gyro coupling solve in [`Calibration::correct`].
pub const MAX_COUPLING_ITERATIONS: usize = 20;

/// Relative change below which the coupling solve counts as converged: relative to the larger
/// of the iterate and the measurement it is computed from.
pub const COUPLING_TOLERANCE: f64 = 1e-13;

/// Where a calibration came from. Every field is optional so hand-written truth files stay short.
///
/// TOML `[provenance]` with `created`, `tool`, `procedure`, `notes` (strings),
/// `temperature-range-c = [low, high]` and `[[provenance.inputs]]` tables with `path` and
/// optional `sha256`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Provenance {
    /// When the file was made, RFC 3339 text (a string, e.g. "2025-03-01T12:00:00Z").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub created: Option<String>,
    /// Tool and version that wrote the file, e.g. "imu-calibrate 0.1.0".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<String>,
    /// The procedure used, e.g. "12-position static + rate table".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub procedure: Option<String>,
    /// Input logs the fit used.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<InputFile>,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
    /// The lowest and highest temperature in the data the fit used, deg C: where the
    /// calibration has been seen to hold (imud's live health says when the sensor leaves it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_range_c: Option<[f64; 2]>,
}

impl Provenance {
    /// True if nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self == &Provenance::default()
    }
}

/// One input file of a fit.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct InputFile {
    /// Path as given to the tool.
    pub path: String,
    /// Lower-case hex SHA-256 of the file's contents.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
}

/// A complete IMU calibration (or simulator truth model): one [`TriadModel`] per triad.
///
/// Absent triads (or empty triad tables) mean "no errors" for that triad.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct Calibration {
    /// Always [`CALIBRATION_FORMAT`]; other values are rejected.
    pub format: String,
    /// Optional human-chosen identifier (e.g. a serial number and date).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// Optional free-text description.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Where the file came from.
    #[serde(default, skip_serializing_if = "Provenance::is_empty")]
    pub provenance: Provenance,
    /// Accelerometer model (unit m/s^2).
    #[serde(default, skip_serializing_if = "TriadModel::is_empty")]
    pub accel: TriadModel,
    /// Gyroscope model (unit rad/s).
    #[serde(default, skip_serializing_if = "TriadModel::is_empty")]
    pub gyro: TriadModel,
    /// Magnetometer model (unit gauss).
    #[serde(default, skip_serializing_if = "TriadModel::is_empty")]
    pub mag: TriadModel,
    /// The prepared inverse, built when parsed or on first use.
    #[serde(skip)]
    inverse: InverseCache,
}

/// A lazily built [`PreparedInverse`] (`None` inside: a model it does not cover). Not part of
/// the calibration's value: equality ignores it and a clone starts empty, so a clone of a
/// changed calibration builds its own. A stale one is never used ([`PreparedInverse::matches`]);
/// a calibration changed in place through its public fields after the cache was filled takes
/// [`Calibration::correct_iterative`] (always correct, only slower) until it is cloned or
/// changed through [`Calibration::triad_mut`], which empties the cache. Loaded calibrations
/// fill it when parsed, so the daemon's first sample does not allocate.
#[derive(Default)]
struct InverseCache(OnceLock<Option<PreparedInverse>>);

impl Clone for InverseCache {
    fn clone(&self) -> Self {
        InverseCache::default()
    }
}

impl PartialEq for InverseCache {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

impl fmt::Debug for InverseCache {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0.get() {
            None => f.write_str("not built"),
            Some(None) => f.write_str("not covered"),
            Some(Some(p)) => write!(f, "{:?}", p.path()),
        }
    }
}

/// The part of a calibration that determines its numbers (hashed by `content_id`).
#[derive(Serialize)]
struct ModelContent<'a> {
    format: &'a str,
    accel: &'a TriadModel,
    gyro: &'a TriadModel,
    mag: &'a TriadModel,
}

impl Default for Calibration {
    fn default() -> Self {
        Calibration::identity()
    }
}

impl Calibration {
    /// No effects at all: forward and inverse are the identity.
    pub fn identity() -> Self {
        Calibration {
            format: CALIBRATION_FORMAT.to_string(),
            id: None,
            description: None,
            provenance: Provenance::default(),
            accel: TriadModel::default(),
            gyro: TriadModel::default(),
            mag: TriadModel::default(),
            inverse: InverseCache::default(),
        }
    }

    /// The model of one triad.
    pub fn triad(&self, t: Triad) -> &TriadModel {
        match t {
            Triad::Accel => &self.accel,
            Triad::Gyro => &self.gyro,
            Triad::Mag => &self.mag,
        }
    }

    /// The model of one triad, mutable. (Also forgets the prepared inverse, which is rebuilt on
    /// the next [`Calibration::correct`].)
    pub fn triad_mut(&mut self, t: Triad) -> &mut TriadModel {
        self.inverse = InverseCache::default();
        match t {
            Triad::Accel => &mut self.accel,
            Triad::Gyro => &mut self.gyro,
            Triad::Mag => &mut self.mag,
        }
    }

    /// Parse and validate a calibration file's text; `source` names the file in messages.
    pub fn from_toml_str(text: &str, source: &str) -> Result<Self, ModelError> {
        let cal: Calibration = toml::from_str(text).map_err(|e| parse_error(source, text, &e))?;
        cal.check().map_err(|e| {
            let path = parse_path(&e.key);
            ModelError::Invalid {
                file: source.to_string(),
                line: line_of_path(text, &path),
                key: e.key,
                message: e.message,
            }
        })?;
        // Build the prepared inverse now, so that the daemon's first sample does not.
        cal.prepared_inverse();
        Ok(cal)
    }

    /// Read, parse and validate a calibration file.
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            file: file.clone(),
            source,
        })?;
        Calibration::from_toml_str(&text, &file)
    }

    /// Check every value (what `from_toml_str` does after parsing); for models built in code.
    pub fn validate(&self) -> Result<(), ModelError> {
        self.check().map_err(|e| ModelError::Invalid {
            file: IN_MEMORY.to_string(),
            key: e.key,
            line: None,
            message: e.message,
        })
    }

    fn check(&self) -> Result<(), InvalidParam> {
        if self.format != CALIBRATION_FORMAT {
            return Err(InvalidParam::new(
                "format",
                format!(
                    "format `{}` is not supported; this build reads `{CALIBRATION_FORMAT}`",
                    self.format
                ),
            ));
        }
        for t in Triad::ALL {
            self.triad(t).validate(t).map_err(|e| e.within(t.name()))?;
        }
        if let Some([lo, hi]) = self.provenance.temperature_range_c
            && !(lo.is_finite() && hi.is_finite() && lo <= hi)
        {
            return Err(InvalidParam::new(
                "provenance.temperature-range-c",
                format!("[{lo}, {hi}] is not a range of temperatures (finite, low first)"),
            ));
        }
        Ok(())
    }

    /// The file text: TOML with a `# units:` comment under every effect table.
    pub fn to_toml_string(&self) -> String {
        // Serializing plain data (strings, finite or non-finite floats, arrays) cannot fail.
        let body = toml::to_string(self).expect("calibration serializes to TOML");
        let mut out = String::from(
            "# imud calibration file. Units: accel m/s^2, gyro rad/s, mag gauss, angles rad,\n\
             # temperatures degC, times s. Omitted effects are absent (no error).\n",
        );
        for line in body.lines() {
            out.push_str(line);
            out.push('\n');
            if let Some(comment) = header_comment(line) {
                out.push_str(&comment);
            }
        }
        out
    }

    /// Write the file atomically (temporary file in the same directory, then rename), so a
    /// daemon hot-reloading it never reads a half-written file.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        let io = |source| ModelError::Io {
            file: path.display().to_string(),
            source,
        };
        let mut tmp_name = path.file_name().unwrap_or_default().to_os_string();
        tmp_name.push(".tmp");
        let tmp = path.with_file_name(tmp_name);
        std::fs::write(&tmp, self.to_toml_string()).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Stable 16-hex-digit id of the model's content (FNV-1a 64 of the canonical TOML of the
    /// format and the three triad models; id, description and provenance are excluded). Equal
    /// models have equal ids across save/load; the daemon reports it as the calibration in force.
    pub fn content_id(&self) -> String {
        let content = ModelContent {
            format: &self.format,
            accel: &self.accel,
            gyro: &self.gyro,
            mag: &self.mag,
        };
        let text = toml::to_string(&content).expect("model serializes to TOML");
        format!("{:016x}", fnv1a64(text.as_bytes()))
    }

    /// Forward model for a whole sample (truth -> measurement, no noise). The vectors of the
    /// conditions come from `truth` (the accel lever arm sees the true angular rate and
    /// acceleration, the gyro g-sensitivity the true specific force); only `c.temp_c` and
    /// `c.time_since_power_on_s` are taken from `c`.
    pub fn forward(&self, truth: &TrueMotion, c: &Conditions) -> Measured {
        let cond = Conditions {
            temp_c: c.temp_c,
            time_since_power_on_s: c.time_since_power_on_s,
            specific_force_m_s2: truth.specific_force_m_s2,
            angular_rate_rad_s: truth.angular_rate_rad_s,
            angular_accel_rad_s2: truth.angular_accel_rad_s2,
        };
        Measured {
            accel_m_s2: self.accel.forward(truth.specific_force_m_s2, &cond),
            gyro_rad_s: self.gyro.forward(truth.angular_rate_rad_s, &cond),
            mag_gauss: self.mag.forward(truth.mag_field_gauss, &cond),
        }
    }

    /// Exact inverse of [`Calibration::forward`] for the daemon, which knows only the
    /// measurement, the temperature, the time since power-on and an estimate of the angular
    /// acceleration. The accel inverse needs the true angular rate (lever arm) and the gyro
    /// inverse the true specific force (g-sensitivity).
    ///
    /// Evaluates the calibration's prepared inverse (gain inverses precomputed once per
    /// calibration; see [`InversePath`]): when every effect is linear and the lever arm and
    /// g-sensitivity are not both present that is one affine map per triad and no iteration;
    /// otherwise the nonlinear per-axis stages are undone with the effects' own code, and the
    /// accel/gyro coupling is iterated only if lever arm and g-sensitivity are both present. It
    /// agrees with [`Calibration::correct_iterative`] to rounding (tests check 1e-12 relative),
    /// and `converged` follows the same rule. Models the prepared form does not cover take
    /// [`Calibration::correct_iterative`]. [`Calibration::inverse_path`] tells which path.
    pub fn correct(
        &self,
        m: &Measured,
        temp_c: f64,
        time_since_power_on_s: f64,
        angular_accel_rad_s2: Vec3,
    ) -> Corrected {
        match self.prepared_inverse() {
            Some(p) => p.correct(m, temp_c, time_since_power_on_s, angular_accel_rad_s2),
            None => self.correct_iterative(m, temp_c, time_since_power_on_s, angular_accel_rad_s2),
        }
    }

    /// Which path [`Calibration::correct`] takes for this calibration, as it is now.
    pub fn inverse_path(&self) -> InversePath {
        self.prepared_inverse()
            .map_or(InversePath::Iterative, PreparedInverse::path)
    }

    /// The prepared inverse if the model is covered and it still matches the model.
    fn prepared_inverse(&self) -> Option<&PreparedInverse> {
        self.inverse
            .0
            .get_or_init(|| PreparedInverse::new(self))
            .as_ref()
            .filter(|p| p.matches(self))
    }

    /// The general inverse, for any calibration (what [`Calibration::correct`] does for a model
    /// the prepared inverse does not cover): each triad's effect chain undone stage by stage, the
    /// accel/gyro coupling solved by fixed-point iteration until both change by less than 1e-13
    /// relative (to the larger of the iterate and its measurement), at most [`MAX_COUPLING_ITERATIONS`] rounds (`converged` reports the outcome).
    /// Without lever arm or g-sensitivity one round suffices.
    pub fn correct_iterative(
        &self,
        m: &Measured,
        temp_c: f64,
        time_since_power_on_s: f64,
        angular_accel_rad_s2: Vec3,
    ) -> Corrected {
        let mut c = Conditions {
            temp_c,
            time_since_power_on_s,
            specific_force_m_s2: m.accel_m_s2,
            angular_rate_rad_s: m.gyro_rad_s,
            angular_accel_rad_s2,
        };
        let coupled =
            self.accel.has(EffectKind::LeverArm) || self.gyro.has(EffectKind::GSensitivity);
        // The lever arm is the first accel stage, so it is undone last; every other accel stage
        // reads only the temperature and the time (a g-sensitivity, which reads the specific
        // force, does not apply to accel, but an unvalidated model may have one). Those stages
        // are undone once, outside the loop: the same operations in the same order as
        // `TriadModel::inverse`, so the iterates are bit for bit those of the plain loop.
        let [lever_arm, accel_rest @ ..] = self.accel.effect_slots();
        debug_assert_eq!(EffectKind::ALL[0], EffectKind::LeverArm);
        let accel_rest = self.accel.g_sensitivity.is_none().then(|| {
            accel_rest
                .iter()
                .rev()
                .flatten()
                .fold(m.accel_m_s2, |v, e| e.inverse(v, &c))
        });
        let mut gyro = self.gyro.inverse(m.gyro_rad_s, &c);
        let mut accel = m.accel_m_s2;
        let mut converged = false;
        for round in 0..MAX_COUPLING_ITERATIONS {
            c.angular_rate_rad_s = gyro;
            let accel_next = match (accel_rest, lever_arm) {
                (Some(y), Some(l)) => l.inverse(y, &c),
                (Some(y), None) => y,
                (None, _) => self.accel.inverse(m.accel_m_s2, &c),
            };
            c.specific_force_m_s2 = accel_next;
            let gyro_next = self.gyro.inverse(m.gyro_rad_s, &c);
            let settled = small_change(accel_next, accel, m.accel_m_s2.amax())
                && small_change(gyro_next, gyro, m.gyro_rad_s.amax());
            accel = accel_next;
            gyro = gyro_next;
            if !coupled || (round > 0 && settled) {
                converged = true;
                break;
            }
        }
        let mag = self.mag.inverse(m.mag_gauss, &c);
        Corrected {
            accel_m_s2: accel,
            gyro_rad_s: gyro,
            mag_gauss: mag,
            converged,
        }
    }
}

/// max|next - prev| <= tol * max(max|next|, `measured_scale`) (component-wise maxima: a
/// Euclidean norm would overflow to inf on a diverging iteration and make inf <= inf look
/// converged), with a tiny absolute floor so that zero vectors converge.
///
/// `measured_scale` is the largest component of the measured vector the iterate is computed
/// from. A corrected component near zero is the difference of terms as large as the
/// measurement, so it carries rounding of that size and may alternate by an ulp of the
/// measurement forever; relative to the tiny result alone such an iterate would never settle.
pub(crate) fn small_change(next: Vec3, prev: Vec3, measured_scale: f64) -> bool {
    let d = (next - prev).amax();
    d.is_finite() && d <= COUPLING_TOLERANCE * next.amax().max(measured_scale).max(1e-9)
}

/// FNV-1a, 64 bit.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The `# ...` lines written under a table header of the serialized file, if any.
fn header_comment(line: &str) -> Option<String> {
    let inner = line.strip_prefix('[')?.strip_suffix(']')?;
    let path = parse_path(inner);
    let (triad, table) = match path.as_slice() {
        [Seg::Key(t), Seg::Key(e)] => (t.parse::<Triad>().ok()?, e.as_str()),
        [Seg::Key(t)] => {
            let t = t.parse::<Triad>().ok()?;
            return Some(format!("# units: residual-rms {}\n", t.unit()));
        }
        _ => return None,
    };
    let u = triad.unit();
    if table == "noise" {
        return Some(format!(
            "# units: white-density {u}/sqrt(Hz); bias-instability {u}; bias-instability-tau-max-s s; random-walk {u}/sqrt(s); quantization-lsb {u}\n"
        ));
    }
    let kind: EffectKind = table.parse().ok()?;
    let units: Vec<String> = kind
        .field_units(triad)
        .into_iter()
        .map(|(f, u)| format!("{f} [{u}]"))
        .collect();
    Some(format!(
        "# {}\n# units: {}; std-error in the same units\n",
        kind.description(),
        units.join("; ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a64_matches_reference_vectors() {
        // Published FNV-1a 64 test vectors.
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn header_comments_state_units() {
        let c = header_comment("[gyro.bias]").expect("effect header gets a comment");
        assert!(c.contains("value [rad/s]"), "{c}");
        let c = header_comment("[accel.noise]").expect("noise header gets a comment");
        assert!(c.contains("white-density m/s^2/sqrt(Hz)"), "{c}");
        assert!(header_comment("[provenance]").is_none());
        assert!(header_comment("value = [1.0]").is_none());
    }
}
