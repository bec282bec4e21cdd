//! Scale-factor nonlinearity: the transfer curve bends quadratically and cubically with input.

use crate::effect::{
    AXES, Effect, EffectDef, InvalidParam, arr3, check_finite, check_std_errors, fill,
    per_unit_pow, prefixed_xyz,
};
use crate::{Conditions, EffectKind, Triad, Vec3, ParamRole};
use serde::{Deserialize, Serialize};

/// Scale nonlinearity. Forward per axis: `y = x + k2 x^2 + k3 x^3`.
///
/// TOML `[<triad>.scale-nonlinearity]`: `quadratic = [x, y, z]` (1/U), `cubic = [x, y, z]`
/// (1/U^2), both default 0, optional `std-error = { quadratic = [...], cubic = [...] }`.
///
/// Invertibility domain: validation requires the local gain `dy/dx = 1 + 2 k2 x + 3 k3 x^2` to
/// stay >= [`MIN_GAIN`] for `|x| <= Triad::validation_range()` (accel 20 g, gyro 35 rad/s,
/// mag 8 gauss), so the curve is strictly increasing there and the inverse is unique. The
/// inverse is exact (closed form without a cubic term, else safeguarded Newton; machine
/// precision) on the whole interval around 0 where the curve is increasing; beyond the turning
/// point of a curve that folds back, the output saturates at the turning point (no input can
/// produce such a measurement).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct ScaleNonlinearity {
    /// k2 per axis, 1/U.
    #[serde(default)]
    pub quadratic: [f64; 3],
    /// k3 per axis, 1/U^2.
    #[serde(default)]
    pub cubic: [f64; 3],
    /// One-sigma standard errors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<NonlinearityStdError>,
}

/// Standard errors of a [`ScaleNonlinearity`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct NonlinearityStdError {
    /// Of `quadratic`, 1/U.
    pub quadratic: [f64; 3],
    /// Of `cubic`, 1/U^2.
    pub cubic: [f64; 3],
}

/// Smallest accepted local gain over the validation range (the curve must stay clearly
/// increasing, or the inverse would amplify noise without bound).
pub const MIN_GAIN: f64 = 0.5;

fn curve(x: f64, k2: f64, k3: f64) -> f64 {
    x * (1.0 + x * (k2 + k3 * x))
}

fn gain(x: f64, k2: f64, k3: f64) -> f64 {
    1.0 + x * (2.0 * k2 + 3.0 * k3 * x)
}

/// The open interval around 0 on which the curve is increasing (ends may be infinite).
fn monotone_interval(k2: f64, k3: f64) -> (f64, f64) {
    // Roots of the gain 3 k3 x^2 + 2 k2 x + 1; none of them is 0 because gain(0) = 1. NaN marks
    // a missing root (it passes neither filter below). An array, not a Vec: this runs for every
    // sample in the daemon, which must not allocate.
    let roots: [f64; 2] = if k3 == 0.0 {
        if k2 == 0.0 {
            [f64::NAN; 2]
        } else {
            [-1.0 / (2.0 * k2), f64::NAN]
        }
    } else {
        let disc = k2 * k2 - 3.0 * k3;
        if disc < 0.0 {
            [f64::NAN; 2]
        } else {
            // Stable quadratic formula: q = -(b + sgn(b) sqrt(b^2 - 4ac)) / 2 with b = 2 k2.
            let q = -(k2 + k2.signum() * disc.sqrt());
            [q / (3.0 * k3), 1.0 / q]
        }
    };
    let lo = roots
        .iter()
        .copied()
        .filter(|r| *r < 0.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let hi = roots
        .iter()
        .copied()
        .filter(|r| *r > 0.0)
        .fold(f64::INFINITY, f64::min);
    (lo, hi)
}

/// Solve `curve(x) = y` for x in the monotone interval around 0 (closed form when `k3 = 0`, else
/// safeguarded Newton).
pub(crate) fn solve(y: f64, k2: f64, k3: f64) -> f64 {
    if k2 == 0.0 && k3 == 0.0 {
        return y;
    }
    if k3 == 0.0 {
        // Quadratic only (the common case): the root on the increasing branch in closed form,
        // 2 y / (1 + sqrt(1 + 4 k2 y)) (no cancellation: the square root is the local gain
        // 1 + 2 k2 x, which is positive there). Past the turning point -1 / (2 k2) no input
        // produces y: saturate there, as below. A NaN measurement stays NaN.
        let d = 1.0 + 4.0 * k2 * y;
        return if d < 0.0 {
            -1.0 / (2.0 * k2)
        } else {
            2.0 * y / (1.0 + d.sqrt())
        };
    }
    solve_within(y, k2, k3, monotone_interval(k2, k3))
}

/// [`solve`] for `k3 != 0` with the curve's monotone interval `(a, b)` given (computed once for
/// many values by [`Effect::inverse_batch`]).
fn solve_within(y: f64, k2: f64, k3: f64, (a, b): (f64, f64)) -> f64 {
    let start = y.abs().max(1.0) * 2.0;
    // Bracket: curve(lo) <= y <= curve(hi), expanding geometrically towards the interval ends.
    let mut hi = start.min(b);
    for _ in 0..2100 {
        if curve(hi, k2, k3) >= y || hi >= b {
            break;
        }
        hi = (hi * 2.0).min(b);
    }
    let mut lo = (-start).max(a);
    for _ in 0..2100 {
        if curve(lo, k2, k3) <= y || lo <= a {
            break;
        }
        lo = (lo * 2.0).max(a);
    }
    if curve(hi, k2, k3) < y {
        return hi; // beyond the turning point: saturate
    }
    if curve(lo, k2, k3) > y {
        return lo;
    }
    let mut x = y.clamp(lo, hi);
    for _ in 0..300 {
        let r = curve(x, k2, k3) - y;
        if r == 0.0 {
            return x;
        }
        if r < 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let mut next = x - r / gain(x, k2, k3);
        // Newton leaving the bracket (or NaN at a zero gain) falls back to bisection.
        if !(next > lo && next < hi) {
            next = lo + 0.5 * (hi - lo);
        }
        if (next - x).abs() <= 2.0 * f64::EPSILON * next.abs()
            || hi - lo <= 2.0 * f64::EPSILON * lo.abs().max(hi.abs())
        {
            return next;
        }
        x = next;
    }
    x
}

impl Effect for ScaleNonlinearity {
    fn kind(&self) -> EffectKind {
        EffectKind::ScaleNonlinearity
    }
    fn param_roles(&self) -> Vec<ParamRole> {
        [2, 3]
            .into_iter()
            .flat_map(|power| (0..3).map(move |axis| ParamRole::Power { power, axis }))
            .collect()
    }
    fn param_names(&self) -> Vec<String> {
        let mut v = prefixed_xyz("quadratic");
        v.extend(prefixed_xyz("cubic"));
        v
    }
    fn param_units(&self, triad: Triad) -> Vec<String> {
        let mut v = vec![per_unit_pow(triad, 1); 3];
        v.extend(vec![per_unit_pow(triad, 2); 3]);
        v
    }
    fn params(&self) -> Vec<f64> {
        [self.quadratic, self.cubic].as_flattened().to_vec()
    }
    fn set_params(&mut self, p: &[f64]) {
        let mut a = [self.quadratic, self.cubic];
        fill(a.as_flattened_mut(), p);
        [self.quadratic, self.cubic] = a;
    }
    fn std_errors(&self) -> Option<Vec<f64>> {
        self.std_error
            .map(|s| [s.quadratic, s.cubic].as_flattened().to_vec())
    }
    fn set_std_errors(&mut self, se: Option<Vec<f64>>) {
        self.std_error = se.map(|s| {
            let mut v = s.clone();
            v.resize(6, 0.0);
            debug_assert_eq!(s.len(), 6, "std-error length mismatch");
            NonlinearityStdError {
                quadratic: arr3(&v[..3]),
                cubic: arr3(&v[3..]),
            }
        });
    }
    fn forward(&self, x: Vec3, _c: &Conditions) -> Vec3 {
        Vec3::from_fn(|i, _| curve(x[i], self.quadratic[i], self.cubic[i]))
    }
    fn inverse(&self, y: Vec3, _c: &Conditions) -> Vec3 {
        Vec3::from_fn(|i, _| solve(y[i], self.quadratic[i], self.cubic[i]))
    }
    fn inverse_batch(&self, ys: &mut [Vec3], _c: &Conditions) {
        // Each axis's monotone interval once for the batch; every value is then solved as
        // `solve` solves it (the same early returns, the same iteration).
        let interval: [Option<(f64, f64)>; 3] = std::array::from_fn(|i| {
            let (k2, k3) = (self.quadratic[i], self.cubic[i]);
            (k3 != 0.0).then(|| monotone_interval(k2, k3))
        });
        for y in ys {
            *y = Vec3::from_fn(|i, _| {
                let (k2, k3) = (self.quadratic[i], self.cubic[i]);
                match interval[i] {
                    Some(ab) => solve_within(y[i], k2, k3, ab),
                    None => solve(y[i], k2, k3),
                }
            });
        }
    }
}

impl EffectDef for ScaleNonlinearity {
    const ID: &'static str = "scale-nonlinearity";
    const DESCRIPTION: &'static str = "scale-factor nonlinearity: output bends with the square and cube of the input, y = x + k2 x^2 + k3 x^3";
    const GAIN: bool = true;
    fn neutral() -> Self {
        ScaleNonlinearity {
            quadratic: [0.0; 3],
            cubic: [0.0; 3],
            std_error: None,
        }
    }
    fn field_units(triad: Triad) -> Vec<(&'static str, String)> {
        vec![
            ("quadratic", per_unit_pow(triad, 1)),
            ("cubic", per_unit_pow(triad, 2)),
        ]
    }
    fn validate(&self, triad: Triad) -> Result<(), InvalidParam> {
        check_finite("quadratic", &self.quadratic)?;
        check_finite("cubic", &self.cubic)?;
        let range = triad.validation_range();
        for (i, axis) in AXES.iter().enumerate() {
            let (k2, k3) = (self.quadratic[i], self.cubic[i]);
            // The gain is a parabola: its minimum over [-R, R] is at an end or at the vertex.
            let mut candidates = vec![-range, range];
            if k3 != 0.0 {
                let v = -k2 / (3.0 * k3);
                if v.abs() <= range {
                    candidates.push(v);
                }
            }
            let (x_min, g_min) = candidates
                .into_iter()
                .map(|x| (x, gain(x, k2, k3)))
                .fold((0.0, f64::INFINITY), |m, c| if c.1 < m.1 { c } else { m });
            if g_min < MIN_GAIN {
                return Err(InvalidParam::new(
                    format!("cubic[{i}]"),
                    format!(
                        "axis {}: the curve y = x + k2 x^2 + k3 x^3 (k2 = {k2}, k3 = {k3}) has gain {g_min:.3} at x = {x_min:.4} {}; it must stay >= {MIN_GAIN} for |x| <= {range} {} so that it can be inverted (k2 is in {}, k3 in {})",
                        axis,
                        triad.unit(),
                        triad.unit(),
                        per_unit_pow(triad, 1),
                        per_unit_pow(triad, 2)
                    ),
                ));
            }
        }
        if let Some(se) = &self.std_error {
            check_std_errors("std-error.quadratic", &se.quadratic)?;
            check_std_errors("std-error.cubic", &se.cubic)?;
        }
        Ok(())
    }
}
