//! Units of text columns: accelerometer and gyro values as written (SI, g, deg/s) or raw counts
//! with a scale and an offset, one for all axes or one per axis.

use super::G0;

/// Raw counts to physical units: `(counts - offset) x scale`, per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CountsAxes {
    /// Physical unit per count, x, y, z.
    pub scale: [f64; 3],
    /// The count that reads zero (mid-scale of an unsigned ADC: 32768 for 16 bits), x, y, z.
    pub offset: [f64; 3],
}

impl CountsAxes {
    fn apply(&self, axis: usize, counts: f64) -> f64 {
        (counts - self.offset[axis]) * self.scale[axis]
    }
}

/// Units of accelerometer columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AccelUnit {
    /// m/s^2.
    MetersPerSecond2,
    /// Standard gravities.
    G,
    /// Counts times a scale in m/s^2 per count.
    Counts(f64),
    /// Counts less an offset, times a scale in m/s^2 per count, per axis (`counts:S@O`).
    CountsOffset(CountsAxes),
}

/// Units of gyro columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GyroUnit {
    /// rad/s.
    RadPerSecond,
    /// deg/s.
    DegPerSecond,
    /// Counts times a scale in rad/s per count.
    Counts(f64),
    /// Counts less an offset, times a scale in rad/s per count, per axis (`counts:S@O`).
    CountsOffset(CountsAxes),
}

/// One number or three (`x,y,z`), each finite (and non-zero when `nonzero`).
fn per_axis(s: &str, nonzero: bool) -> Option<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .ok()?;
    let v = match v.as_slice() {
        [k] => [*k; 3],
        [x, y, z] => [*x, *y, *z],
        _ => return None,
    };
    v.iter()
        .all(|k| k.is_finite() && (!nonzero || *k != 0.0))
        .then_some(v)
}

/// A parsed `counts:` unit: the plain scale (`counts:S`, as before offsets existed) or scales
/// and offsets per axis.
enum CountsSpec {
    Scale(f64),
    Axes(CountsAxes),
}

/// `counts:SCALE[@OFFSET]`, SCALE and OFFSET each one number or `x,y,z`; `None` when `s` is
/// not a `counts:` unit at all.
fn counts_spec(s: &str, unit: &str) -> Option<Result<CountsSpec, String>> {
    let v = s.strip_prefix("counts:")?;
    let (scale, offset) = match v.split_once('@') {
        Some((k, o)) => (k, Some(o)),
        None => (v, None),
    };
    let bad = || {
        format!(
            "`{s}`: write counts:SCALE with SCALE the {unit} per count, e.g. counts:0.00119, \
             or counts:SCALE@OFFSET with the count that reads zero, e.g. counts:0.00241@32768; \
             SCALE and OFFSET may each be one number or x,y,z (counts:0.0024,0.0025,0.0024@32768)"
        )
    };
    Some(
        match (per_axis(scale, true), offset.map(|o| per_axis(o, false))) {
            (Some(k), None) if k[0] == k[1] && k[1] == k[2] && !scale.contains(',') => {
                Ok(CountsSpec::Scale(k[0]))
            }
            (Some(k), None) => Ok(CountsSpec::Axes(CountsAxes {
                scale: k,
                offset: [0.0; 3],
            })),
            (Some(k), Some(Some(o))) => Ok(CountsSpec::Axes(CountsAxes {
                scale: k,
                offset: o,
            })),
            _ => Err(bad()),
        },
    )
}

impl std::str::FromStr for AccelUnit {
    type Err = String;
    /// `m/s2` (or `m_s2`), `g`, or `counts:SCALE[@OFFSET]` (SCALE in m/s^2 per count; each
    /// one number or `x,y,z`).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "m/s2" | "m/s^2" | "m_s2" => Ok(AccelUnit::MetersPerSecond2),
            "g" => Ok(AccelUnit::G),
            t => match counts_spec(t, "m/s^2") {
                Some(Ok(CountsSpec::Scale(k))) => Ok(AccelUnit::Counts(k)),
                Some(Ok(CountsSpec::Axes(c))) => Ok(AccelUnit::CountsOffset(c)),
                Some(Err(e)) => Err(e),
                None => Err(format!(
                    "unknown accel unit `{t}`: use m/s2, g or counts:SCALE[@OFFSET] (m/s^2 per \
                     count, the count that reads zero)"
                )),
            },
        }
    }
}

impl std::str::FromStr for GyroUnit {
    type Err = String;
    /// `rad/s` (or `rad_s`), `deg/s` (or `deg_s`), or `counts:SCALE[@OFFSET]` (SCALE in rad/s
    /// per count; each one number or `x,y,z`).
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "rad/s" | "rad_s" => Ok(GyroUnit::RadPerSecond),
            "deg/s" | "deg_s" => Ok(GyroUnit::DegPerSecond),
            t => match counts_spec(t, "rad/s") {
                Some(Ok(CountsSpec::Scale(k))) => Ok(GyroUnit::Counts(k)),
                Some(Ok(CountsSpec::Axes(c))) => Ok(GyroUnit::CountsOffset(c)),
                Some(Err(e)) => Err(e),
                None => Err(format!(
                    "unknown gyro unit `{t}`: use rad/s, deg/s or counts:SCALE[@OFFSET] (rad/s \
                     per count, the count that reads zero)"
                )),
            },
        }
    }
}

impl AccelUnit {
    /// The value `x` of axis `axis` (0 x, 1 y, 2 z) in m/s^2.
    pub(super) fn to_m_s2(self, axis: usize, x: f64) -> f64 {
        match self {
            AccelUnit::MetersPerSecond2 => x,
            AccelUnit::G => x * G0,
            AccelUnit::Counts(k) => x * k,
            AccelUnit::CountsOffset(c) => c.apply(axis, x),
        }
    }
}

impl GyroUnit {
    /// The value `x` of axis `axis` (0 x, 1 y, 2 z) in rad/s.
    pub(super) fn to_rad_s(self, axis: usize, x: f64) -> f64 {
        match self {
            GyroUnit::RadPerSecond => x,
            GyroUnit::DegPerSecond => x.to_radians(),
            GyroUnit::Counts(k) => x * k,
            GyroUnit::CountsOffset(c) => c.apply(axis, x),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_with_offsets_one_or_per_axis() {
        assert_eq!(
            "counts:0.5".parse::<AccelUnit>(),
            Ok(AccelUnit::Counts(0.5))
        );
        let u: GyroUnit = "counts:0.00241@32768".parse().unwrap();
        assert_eq!(
            u,
            GyroUnit::CountsOffset(CountsAxes {
                scale: [0.00241; 3],
                offset: [32768.0; 3]
            })
        );
        assert!((u.to_rad_s(1, 32768.0 + 1000.0) - 2.41).abs() < 1e-12);
        let a: AccelUnit = "counts:0.001,0.002,0.003@100,200,300".parse().unwrap();
        assert_eq!(a.to_m_s2(0, 1100.0), 1.0);
        assert_eq!(a.to_m_s2(1, 700.0), 1.0);
        assert!((a.to_m_s2(2, 300.0 - 1000.0) + 3.0).abs() < 1e-12);
        for bad in [
            "counts:0@32768",
            "counts:1,2@3",
            "counts:1@x",
            "counts:",
            "counts:1@",
        ] {
            let e = bad.parse::<AccelUnit>().unwrap_err();
            assert!(e.contains("counts:SCALE@OFFSET"), "{bad}: {e}");
        }
    }
}
