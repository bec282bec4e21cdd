//! The closed-form inverse of a calibration whose effects are all linear: the fast path that
//! [`Calibration::correct`](crate::Calibration::correct) takes instead of the effect chains and
//! the accel/gyro fixed-point iteration.
//!
//! # When the inverse is affine
//!
//! With only linear effects a triad's forward model (canonical order) is
//!
//! `y = D (I + M) (x + l) + b + b_T(T) + w(t) + G f`
//!
//! (`D = diag(1 + s)` scale, `M` misalignment, `l` the accel lever-arm term, `b` bias, `b_T` the
//! temperature bias, `w` the warm-up transient, `G f` the gyro g-sensitivity at the true specific
//! force `f`), so its inverse is
//!
//! `x = A (y - G f - w(t) - b_T(T) - b) - l`, with `A = (I + M)^-1 D^-1` precomputed.
//!
//! For one frame the temperature `T` and the time `t` are known, so `b_T` and `w` are constants
//! (evaluated per frame with the effects' own formulas) and the map is affine in `y`. For the joint
//! accel/gyro inverse:
//!
//! - **g-sensitivity, no lever arm**: `f` comes from the accel map alone, then
//!   `w = A_g (w_m - G f - ...)`: affine in the measured `(accel, gyro)`, no iteration.
//! - **lever arm, no g-sensitivity**: `l = w x (w x r) + a x r`. With the frame's angular
//!   acceleration `a` (the daemon's estimate) `a x r` is a constant; `w x (w x r)` is quadratic
//!   in the true rate `w`, but `w` comes from the gyro map alone, so the term is evaluated once at
//!   the corrected rate ([`LeverArm::term_m_s2`], exactly what the iteration evaluates): closed
//!   form, but not affine in the measured gyro.
//! - **both**: `w` depends on `f` through `G` and `f` on `w` through `w x (w x r)`, a quadratic
//!   implicit system: the iteration.
//! - **temp-scale**: its factor multiplies the gain matrix by a polynomial of `T`; affine per
//!   frame, but `A` would have to be rebuilt whenever the temperature changes. Not in the fast
//!   path (the iteration handles it); with the 3DM-GX1 class (no temperature scale error seen)
//!   this costs nothing.
//! - **asymmetric scale, scale nonlinearity**: nonlinear in `y`: the iteration.
//!
//! # Staleness
//!
//! `Calibration`'s fields are public and mutated in place across the workspace, so the map keeps
//! a copy of the effect parameters it was built from and is used only while the calibration
//! holds exactly those effects ([`AffineInverse::matches`], a comparison of a few dozen numbers
//! per sample, no allocation). A calibration changed after its map was built falls back to the
//! iteration, which is always correct.

use crate::calibration::small_change;
use crate::{
    Bias, Calibration, Conditions, Corrected, EffectKind, GSensitivity, LeverArm, Mat3, Measured,
    Misalignment, Scale, TempBias, Triad, TriadModel, Vec3, Warmup,
};

/// Whether effect `k` is linear (affine per frame) and so allowed in the fast path. Exhaustive on
/// purpose: a new effect does not compile until it is classified here.
pub(crate) fn is_linear(k: EffectKind) -> bool {
    match k {
        EffectKind::LeverArm
        | EffectKind::Misalignment
        | EffectKind::Scale
        | EffectKind::Bias
        | EffectKind::TempBias
        | EffectKind::Warmup
        | EffectKind::GSensitivity => true,
        EffectKind::AsymmetricScale | EffectKind::TempScale | EffectKind::ScaleNonlinearity => {
            false
        }
    }
}

/// The linear effects of one triad as they were when the map was built.
#[derive(Clone, Debug, PartialEq)]
struct LinearEffects {
    lever_arm: Option<LeverArm>,
    misalignment: Option<Misalignment>,
    scale: Option<Scale>,
    bias: Option<Bias>,
    temp_bias: Option<TempBias>,
    warmup: Option<Warmup>,
    g_sensitivity: Option<GSensitivity>,
}

impl LinearEffects {
    fn of(m: &TriadModel) -> Self {
        LinearEffects {
            lever_arm: m.lever_arm.clone(),
            misalignment: m.misalignment.clone(),
            scale: m.scale.clone(),
            bias: m.bias.clone(),
            temp_bias: m.temp_bias.clone(),
            warmup: m.warmup.clone(),
            g_sensitivity: m.g_sensitivity.clone(),
        }
    }

    /// True if `m` has exactly these effects (and so no nonlinear one). Allocation-free.
    fn matches(&self, m: &TriadModel) -> bool {
        m.asymmetric_scale.is_none()
            && m.temp_scale.is_none()
            && m.scale_nonlinearity.is_none()
            && self.lever_arm == m.lever_arm
            && self.misalignment == m.misalignment
            && self.scale == m.scale
            && self.bias == m.bias
            && self.temp_bias == m.temp_bias
            && self.warmup == m.warmup
            && self.g_sensitivity == m.g_sensitivity
    }
}

/// The precomputed inverse of one triad's linear stages.
#[derive(Clone, Debug)]
struct TriadAffine {
    source: LinearEffects,
    /// `(I + M)^-1 D^-1` (1/1), `None` without misalignment and scale.
    gain_inverse: Option<Mat3>,
    /// Bias, in the triad's unit.
    bias: Option<Vec3>,
    /// g-sensitivity `G`, (rad/s)/(m/s^2) (gyro only).
    g_matrix: Option<Mat3>,
}

impl TriadAffine {
    /// `None` if the triad has a nonlinear effect, an effect that does not apply to it, or a
    /// gain matrix that is singular or not finite (left to the iteration, which reports NaN).
    fn new(m: &TriadModel, triad: Triad) -> Option<Self> {
        if m.effects()
            .iter()
            .any(|e| !is_linear(e.kind()) || !e.kind().applies_to(triad))
        {
            return None;
        }
        let mut gain_inverse = None;
        if let Some(mis) = &m.misalignment {
            gain_inverse = Some(mis.matrix().try_inverse()?);
        }
        if let Some(s) = &m.scale {
            let d_inv = Mat3::from_diagonal(&Vec3::from(s.value).add_scalar(1.0).map(|d| 1.0 / d));
            gain_inverse = Some(gain_inverse.map_or(d_inv, |a| a * d_inv));
        }
        if gain_inverse.is_some_and(|a| !a.iter().all(|v| v.is_finite())) {
            return None;
        }
        Some(TriadAffine {
            source: LinearEffects::of(m),
            gain_inverse,
            bias: m.bias.as_ref().map(|b| Vec3::from(b.value)),
            g_matrix: m.g_sensitivity.as_ref().map(GSensitivity::g_matrix),
        })
    }

    /// Undo every stage but the lever arm: `A (y - G f - w(t) - b_T(T) - b)`, the offsets
    /// subtracted in the effect chain's order so that they round as they do there.
    fn undo_offsets_and_gain(&self, y: Vec3, c: &Conditions) -> Vec3 {
        let mut v = y;
        if let Some(g) = &self.g_matrix {
            v -= g * c.specific_force_m_s2;
        }
        if let Some(w) = &self.source.warmup {
            v -= w.offset(c.time_since_power_on_s);
        }
        if let Some(tb) = &self.source.temp_bias {
            v -= tb.offset(c.temp_c);
        }
        if let Some(b) = &self.bias {
            v -= b;
        }
        match &self.gain_inverse {
            Some(a) => a * v,
            None => v,
        }
    }
}

/// The closed-form inverse of a calibration whose effects are all linear (see the module docs
/// for exactly which). Built by [`AffineInverse::new`]; used by `Calibration::correct` while
/// [`AffineInverse::matches`] holds.
#[derive(Clone, Debug)]
pub(crate) struct AffineInverse {
    accel: TriadAffine,
    gyro: TriadAffine,
    mag: TriadAffine,
}

impl AffineInverse {
    /// The map for `cal`, or `None` if some effect is nonlinear, temperature-scaled, misplaced,
    /// or the lever arm and g-sensitivity are both present (a quadratic coupling).
    pub(crate) fn new(cal: &Calibration) -> Option<Self> {
        let inv = AffineInverse {
            accel: TriadAffine::new(&cal.accel, Triad::Accel)?,
            gyro: TriadAffine::new(&cal.gyro, Triad::Gyro)?,
            mag: TriadAffine::new(&cal.mag, Triad::Mag)?,
        };
        let quadratic_coupling =
            inv.accel.source.lever_arm.is_some() && inv.gyro.g_matrix.is_some();
        (!quadratic_coupling).then_some(inv)
    }

    /// True while `cal` holds exactly the effects the map was built from.
    pub(crate) fn matches(&self, cal: &Calibration) -> bool {
        self.accel.source.matches(&cal.accel)
            && self.gyro.source.matches(&cal.gyro)
            && self.mag.source.matches(&cal.mag)
    }

    /// The same result as `Calibration::correct_iterative` (to rounding), in closed form. The
    /// `converged` flag follows the iteration's rule: always true without coupling, otherwise
    /// true when the iteration's settling test would pass on the result (it fails only on
    /// non-finite values).
    pub(crate) fn correct(
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
        let accel_partial = self.accel.undo_offsets_and_gain(m.accel_m_s2, &c);
        let (accel, gyro) = match &self.accel.source.lever_arm {
            // No g-sensitivity here (`new`): the rate does not depend on the specific force.
            Some(lever) => {
                let gyro = self.gyro.undo_offsets_and_gain(m.gyro_rad_s, &c);
                c.angular_rate_rad_s = gyro;
                (accel_partial - lever.term_m_s2(&c), gyro)
            }
            None => {
                c.specific_force_m_s2 = accel_partial;
                let gyro = self.gyro.undo_offsets_and_gain(m.gyro_rad_s, &c);
                (accel_partial, gyro)
            }
        };
        c.specific_force_m_s2 = accel;
        c.angular_rate_rad_s = gyro;
        let mag = self.mag.undo_offsets_and_gain(m.mag_gauss, &c);
        let coupled = self.accel.source.lever_arm.is_some() || self.gyro.g_matrix.is_some();
        Corrected {
            accel_m_s2: accel,
            gyro_rad_s: gyro,
            mag_gauss: mag,
            converged: !coupled || (small_change(accel, accel) && small_change(gyro, gyro)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_nonlinear_effect_disables_the_map_and_breaks_the_match() {
        let linear = Calibration::identity();
        let inv = AffineInverse::new(&linear).expect("identity is linear");
        for k in EffectKind::ALL {
            for t in Triad::ALL.into_iter().filter(|t| k.applies_to(*t)) {
                let mut cal = Calibration::identity();
                cal.triad_mut(t).add(k);
                assert_eq!(
                    AffineInverse::new(&cal).is_some(),
                    is_linear(k),
                    "{k} on {t}"
                );
                // Any added effect (even a neutral one) makes a map built without it stale.
                assert!(!inv.matches(&cal), "{k} on {t}");
            }
        }
    }

    #[test]
    fn misplaced_effects_and_the_quadratic_coupling_take_the_iteration() {
        let mut cal = Calibration::identity();
        cal.mag.add(EffectKind::GSensitivity);
        assert!(AffineInverse::new(&cal).is_none());
        let mut cal = Calibration::identity();
        cal.accel.add(EffectKind::LeverArm);
        assert!(AffineInverse::new(&cal).is_some());
        cal.gyro.add(EffectKind::GSensitivity);
        assert!(AffineInverse::new(&cal).is_none());
    }

    #[test]
    fn a_singular_gain_is_left_to_the_iteration() {
        let mut cal = Calibration::identity();
        cal.accel.add(EffectKind::Scale);
        cal.accel.scale.as_mut().expect("added").value = [-1.0, 0.0, 0.0];
        assert!(AffineInverse::new(&cal).is_none());
        let mut cal = Calibration::identity();
        cal.gyro.add(EffectKind::Misalignment);
        let m = cal.gyro.misalignment.as_mut().expect("added");
        (m.xy, m.yx) = (1.0, 1.0);
        assert!(AffineInverse::new(&cal).is_none());
    }
}
