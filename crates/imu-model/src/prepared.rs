//! The prepared inverse of a calibration: what [`Calibration::correct`] evaluates per sample
//! instead of the effect chains, with the gain inverse precomputed and, for a calibration whose
//! effects are all linear, no iteration at all (one affine map per triad).
//!
//! # Structure of every triad's inverse
//!
//! Undoing the canonical order in reverse, every triad's inverse has the same shape:
//!
//! `x = A P(y - G f - w(t) - b_T(T) - b) - l`, with `A = (I + M)^-1 D^-1`
//!
//! (`G f` gyro g-sensitivity at the true specific force `f`, `w` warm-up, `b_T` temperature
//! bias, `b` bias, `P` the per-axis nonlinear stages undone in order: scale nonlinearity,
//! temperature scale, asymmetric scale; `D = diag(1 + s)` scale, `M` misalignment, `l` the accel
//! lever-arm term). `A` is computed once here instead of an LU factorisation per stage call; the
//! offsets are subtracted and `P` is evaluated exactly as the effect chain does, with the
//! effects' own code.
//!
//! # When the joint inverse is affine
//!
//! For one frame the temperature `T`, the time `t` and the angular-acceleration estimate `a` are
//! known, so `w(t)` and `b_T(T)` are constants. With `P` the identity (no scale nonlinearity,
//! asymmetric scale or temperature scale) each triad's map is affine in `y`, and jointly:
//!
//! - **g-sensitivity, no lever arm**: `f` comes from the accel map alone, then
//!   `w = A_g (w_m - G f - ...)`: affine in the measured `(accel, gyro)`, no iteration
//!   ([`InversePath::Affine`]).
//! - **lever arm, no g-sensitivity**: `l = w x (w x r) + a x r`; `a x r` is a constant,
//!   `w x (w x r)` is quadratic in the rate, but the rate comes from the gyro map alone, so the
//!   term is evaluated once at the corrected rate with [`LeverArm::term_m_s2`], exactly as the
//!   iteration evaluates it. Closed form, no iteration; affine up to that explicit term (also
//!   reported as [`InversePath::Affine`]).
//! - **lever arm and g-sensitivity**: the rate depends on `f` through `G` and `f` on the rate
//!   through `w x (w x r)`, a quadratic implicit system: the fixed-point iteration of
//!   [`Calibration::correct_iterative`] (same start, same settling rule, same budget), but each
//!   round costs two small matrix products instead of two effect chains.
//! - **temp-scale**: affine per frame, but its factor changes `A` whenever the temperature
//!   changes. Chosen: not folded into `A` (no per-temperature rebuild); it is evaluated as a
//!   per-axis stage inside `P` like the nonlinear ones ([`InversePath::Prepared`]).
//! - **scale nonlinearity, asymmetric scale**: nonlinear in `y`; inside `P`
//!   ([`InversePath::Prepared`]).
//!
//! # Staleness
//!
//! `Calibration`'s fields are public and mutated in place across the workspace, so the prepared
//! inverse keeps a copy of the effects it was built from, evaluates only that copy, and is used
//! only while the calibration holds exactly those effects ([`PreparedInverse::matches`]: a
//! comparison of a few dozen numbers per sample, no allocation).

use crate::calibration::small_change;
use crate::{
    AsymmetricScale, Bias, Calibration, Conditions, Corrected, Effect, EffectKind, GSensitivity,
    LeverArm, MAX_COUPLING_ITERATIONS, Mat3, Measured, Misalignment, Scale, ScaleNonlinearity,
    TempBias, TempScale, Triad, TriadModel, Vec3, Warmup,
};

/// How [`Calibration::correct`] inverts a calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InversePath {
    /// Every effect linear (lever arm, misalignment, scale, bias, temp-bias, warm-up,
    /// g-sensitivity), not lever arm and g-sensitivity together: one precomputed affine map per
    /// triad (plus the lever-arm term at the corrected rate), no iteration.
    Affine,
    /// Precomputed gain inverses around the per-axis nonlinear stages (scale nonlinearity,
    /// asymmetric scale, temperature scale); the accel/gyro coupling iterated only when lever
    /// arm and g-sensitivity are both present.
    Prepared,
    /// The effect chains and the fixed-point iteration ([`Calibration::correct_iterative`]):
    /// models the prepared form does not cover (an effect on a triad it does not apply to, a
    /// singular gain) or changed in place after the prepared inverse was built.
    Iterative,
}

/// Whether effect `k` is linear (affine per frame, no change of gain with temperature).
/// Exhaustive on purpose: a new effect does not compile until it is classified here (and placed
/// in [`TriadInverse::undo_offsets_and_gain`]).
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

/// The effects of one triad as they were when the inverse was built (noise and residual
/// statistics are not part of the inverse and are not copied).
#[derive(Clone, Debug, PartialEq)]
struct Effects {
    lever_arm: Option<LeverArm>,
    misalignment: Option<Misalignment>,
    scale: Option<Scale>,
    asymmetric_scale: Option<AsymmetricScale>,
    temp_scale: Option<TempScale>,
    scale_nonlinearity: Option<ScaleNonlinearity>,
    bias: Option<Bias>,
    temp_bias: Option<TempBias>,
    warmup: Option<Warmup>,
    g_sensitivity: Option<GSensitivity>,
}

impl Effects {
    fn of(m: &TriadModel) -> Self {
        Effects {
            lever_arm: m.lever_arm.clone(),
            misalignment: m.misalignment.clone(),
            scale: m.scale.clone(),
            asymmetric_scale: m.asymmetric_scale.clone(),
            temp_scale: m.temp_scale.clone(),
            scale_nonlinearity: m.scale_nonlinearity.clone(),
            bias: m.bias.clone(),
            temp_bias: m.temp_bias.clone(),
            warmup: m.warmup.clone(),
            g_sensitivity: m.g_sensitivity.clone(),
        }
    }

    /// True if `m` has exactly these effects. Allocation-free.
    fn matches(&self, m: &TriadModel) -> bool {
        self.lever_arm == m.lever_arm
            && self.misalignment == m.misalignment
            && self.scale == m.scale
            && self.asymmetric_scale == m.asymmetric_scale
            && self.temp_scale == m.temp_scale
            && self.scale_nonlinearity == m.scale_nonlinearity
            && self.bias == m.bias
            && self.temp_bias == m.temp_bias
            && self.warmup == m.warmup
            && self.g_sensitivity == m.g_sensitivity
    }
}

/// The prepared inverse of one triad.
#[derive(Clone, Debug)]
struct TriadInverse {
    source: Effects,
    /// `(I + M)^-1 D^-1` (1/1), `None` without misalignment and scale.
    gain_inverse: Option<Mat3>,
    /// Bias, in the triad's unit.
    bias: Option<Vec3>,
    /// g-sensitivity `G`, (rad/s)/(m/s^2) (gyro only).
    g_matrix: Option<Mat3>,
    /// True if every effect is linear (`P` is the identity).
    linear: bool,
}

impl TriadInverse {
    /// `None` if the triad has an effect that does not apply to it (only an unvalidated model
    /// can), or a gain that is singular or not finite (left to the chain, which reports NaN).
    fn new(m: &TriadModel, triad: Triad) -> Option<Self> {
        let kinds = m.effects().iter().map(|e| e.kind()).collect::<Vec<_>>();
        if kinds.iter().any(|k| !k.applies_to(triad)) {
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
        Some(TriadInverse {
            source: Effects::of(m),
            gain_inverse,
            bias: m.bias.as_ref().map(|b| Vec3::from(b.value)),
            g_matrix: m.g_sensitivity.as_ref().map(GSensitivity::g_matrix),
            linear: kinds.into_iter().all(is_linear),
        })
    }

    /// Undo every stage but the lever arm: `A P(y - G f - w(t) - b_T(T) - b)`, the offsets and
    /// `P` in the effect chain's order and with its code, so they round as they do there.
    fn undo_offsets_and_gain(&self, y: Vec3, c: &Conditions) -> Vec3 {
        let e = &self.source;
        let mut v = y;
        if let Some(g) = &self.g_matrix {
            v -= g * c.specific_force_m_s2;
        }
        if let Some(w) = &e.warmup {
            v -= w.offset(c.time_since_power_on_s);
        }
        if let Some(tb) = &e.temp_bias {
            v -= tb.offset(c.temp_c);
        }
        if let Some(b) = &self.bias {
            v -= b;
        }
        if let Some(nl) = &e.scale_nonlinearity {
            v = nl.inverse(v, c);
        }
        if let Some(ts) = &e.temp_scale {
            v = ts.inverse(v, c);
        }
        if let Some(a) = &e.asymmetric_scale {
            v = a.inverse(v, c);
        }
        match &self.gain_inverse {
            Some(a) => a * v,
            None => v,
        }
    }
}

/// A calibration that can no longer change, with its inverse prepared once: the per-sample
/// path of a daemon that holds a calibration until it loads another. `correct` skips the
/// per-call check [`Calibration::correct`] makes that the public fields still hold the effects
/// the inverse was prepared from (about 30 ns a sample), because nothing can change them: the
/// calibration is only reachable read-only (`Deref`).
#[derive(Clone, Debug)]
pub struct SealedCalibration {
    calibration: Calibration,
    inverse: Option<PreparedInverse>,
}

impl SealedCalibration {
    /// Seals `calibration`, preparing its inverse.
    pub fn new(calibration: Calibration) -> SealedCalibration {
        let inverse = PreparedInverse::new(&calibration);
        SealedCalibration {
            calibration,
            inverse,
        }
    }

    /// The same result as [`Calibration::correct`] on the sealed calibration.
    pub fn correct(
        &self,
        m: &Measured,
        temp_c: f64,
        time_since_power_on_s: f64,
        angular_accel_rad_s2: Vec3,
    ) -> Corrected {
        match &self.inverse {
            Some(p) => p.correct(m, temp_c, time_since_power_on_s, angular_accel_rad_s2),
            None => self.calibration.correct_iterative(
                m,
                temp_c,
                time_since_power_on_s,
                angular_accel_rad_s2,
            ),
        }
    }
}

impl std::ops::Deref for SealedCalibration {
    type Target = Calibration;
    fn deref(&self) -> &Calibration {
        &self.calibration
    }
}

/// The prepared inverse of a whole calibration (see the module docs). Built by
/// [`PreparedInverse::new`]; used by `Calibration::correct` while [`PreparedInverse::matches`]
/// holds.
#[derive(Clone, Debug)]
pub(crate) struct PreparedInverse {
    accel: TriadInverse,
    gyro: TriadInverse,
    mag: TriadInverse,
}

impl PreparedInverse {
    /// The prepared inverse of `cal`, or `None` for a model it does not cover (an effect on a
    /// triad it does not apply to, a singular or non-finite gain).
    pub(crate) fn new(cal: &Calibration) -> Option<Self> {
        Some(PreparedInverse {
            accel: TriadInverse::new(&cal.accel, Triad::Accel)?,
            gyro: TriadInverse::new(&cal.gyro, Triad::Gyro)?,
            mag: TriadInverse::new(&cal.mag, Triad::Mag)?,
        })
    }

    /// True while `cal` holds exactly the effects this was built from.
    pub(crate) fn matches(&self, cal: &Calibration) -> bool {
        self.accel.source.matches(&cal.accel)
            && self.gyro.source.matches(&cal.gyro)
            && self.mag.source.matches(&cal.mag)
    }

    /// [`InversePath::Affine`] or [`InversePath::Prepared`].
    pub(crate) fn path(&self) -> InversePath {
        let quadratic_coupling =
            self.accel.source.lever_arm.is_some() && self.gyro.g_matrix.is_some();
        if self.accel.linear && self.gyro.linear && self.mag.linear && !quadratic_coupling {
            InversePath::Affine
        } else {
            InversePath::Prepared
        }
    }

    /// The result of `Calibration::correct_iterative` (to rounding). `converged` follows the
    /// iteration's rule: without coupling always true; with one coupling effect true when the
    /// iteration's settling test passes on the result (it fails only on non-finite values);
    /// with both, the same iteration (start, settling test, budget) on the prepared stages.
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
        // Accel has no g-sensitivity (`TriadInverse::new`): this reads only T and t.
        let accel_partial = self.accel.undo_offsets_and_gain(m.accel_m_s2, &c);
        let lever_arm = self.accel.source.lever_arm.as_ref();
        let g_sensitivity = self.gyro.g_matrix.is_some();
        let (accel, gyro, converged) = match lever_arm {
            None => {
                c.specific_force_m_s2 = accel_partial;
                let gyro = self.gyro.undo_offsets_and_gain(m.gyro_rad_s, &c);
                let settled = small_change(accel_partial, accel_partial, 0.0)
                    && small_change(gyro, gyro, 0.0);
                (accel_partial, gyro, !g_sensitivity || settled)
            }
            // The rate does not depend on the specific force: one pass.
            Some(lever) if !g_sensitivity => {
                let gyro = self.gyro.undo_offsets_and_gain(m.gyro_rad_s, &c);
                c.angular_rate_rad_s = gyro;
                let accel = accel_partial - lever.term_m_s2(&c);
                (
                    accel,
                    gyro,
                    small_change(accel, accel, 0.0) && small_change(gyro, gyro, 0.0),
                )
            }
            Some(lever) => self.iterate(m, accel_partial, lever, &mut c),
        };
        c.specific_force_m_s2 = accel;
        c.angular_rate_rad_s = gyro;
        let mag = self.mag.undo_offsets_and_gain(m.mag_gauss, &c);
        Corrected {
            accel_m_s2: accel,
            gyro_rad_s: gyro,
            mag_gauss: mag,
            converged,
        }
    }

    /// The coupling iteration of `Calibration::correct_iterative` (lever arm and
    /// g-sensitivity), on the prepared stages: `(accel, gyro, converged)`.
    fn iterate(
        &self,
        m: &Measured,
        accel_partial: Vec3,
        lever: &LeverArm,
        c: &mut Conditions,
    ) -> (Vec3, Vec3, bool) {
        let mut gyro = self.gyro.undo_offsets_and_gain(m.gyro_rad_s, c);
        let mut accel = m.accel_m_s2;
        for round in 0..MAX_COUPLING_ITERATIONS {
            c.angular_rate_rad_s = gyro;
            let accel_next = accel_partial - lever.term_m_s2(c);
            c.specific_force_m_s2 = accel_next;
            let gyro_next = self.gyro.undo_offsets_and_gain(m.gyro_rad_s, c);
            let settled = small_change(accel_next, accel, m.accel_m_s2.amax())
                && small_change(gyro_next, gyro, m.gyro_rad_s.amax());
            accel = accel_next;
            gyro = gyro_next;
            if round > 0 && settled {
                return (accel, gyro, true);
            }
        }
        (accel, gyro, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_effect_is_classified_and_any_change_breaks_the_match() {
        let identity = Calibration::identity();
        let inv = PreparedInverse::new(&identity).expect("identity is covered");
        assert_eq!(inv.path(), InversePath::Affine);
        for k in EffectKind::ALL {
            for t in Triad::ALL.into_iter().filter(|t| k.applies_to(*t)) {
                let mut cal = Calibration::identity();
                cal.triad_mut(t).add(k);
                let built = PreparedInverse::new(&cal).expect("covered");
                let expected = if is_linear(k) {
                    InversePath::Affine
                } else {
                    InversePath::Prepared
                };
                assert_eq!(built.path(), expected, "{k} on {t}");
                // Any added effect (even a neutral one) makes an inverse built without it stale.
                assert!(!inv.matches(&cal), "{k} on {t}");
                assert!(built.matches(&cal), "{k} on {t}");
            }
        }
    }

    #[test]
    fn misplaced_effects_are_not_covered_and_the_quadratic_coupling_is_not_affine() {
        let mut cal = Calibration::identity();
        cal.mag.add(EffectKind::GSensitivity);
        assert!(PreparedInverse::new(&cal).is_none());
        let mut cal = Calibration::identity();
        cal.accel.add(EffectKind::LeverArm);
        let path = |cal: &Calibration| PreparedInverse::new(cal).expect("covered").path();
        assert_eq!(path(&cal), InversePath::Affine);
        cal.gyro.add(EffectKind::GSensitivity);
        assert_eq!(path(&cal), InversePath::Prepared);
    }

    #[test]
    fn a_singular_gain_is_left_to_the_chain() {
        let mut cal = Calibration::identity();
        cal.accel.add(EffectKind::Scale);
        cal.accel.scale.as_mut().expect("added").value = [-1.0, 0.0, 0.0];
        assert!(PreparedInverse::new(&cal).is_none());
        let mut cal = Calibration::identity();
        cal.gyro.add(EffectKind::Misalignment);
        let m = cal.gyro.misalignment.as_mut().expect("added");
        (m.xy, m.yx) = (1.0, 1.0);
        assert!(PreparedInverse::new(&cal).is_none());
    }
}
