//! The gyro's sign, checked against gravity. A Ferraris turn's sense comes from the gyro itself
//! (the procedure has no table to say it), so a gyro axis whose sign is flipped (a unit that
//! reports the rotation the other way, or counts scaled with the wrong sign) would be fitted a
//! positive gain on a reversed turn and calibrate every rotation backwards. Gravity says the
//! true sense wherever the unit tilts: the specific force of a unit that only rotates changes
//! as `df/dt = -w x f` in the sensor frame. Over the samples that move, the change of the
//! accelerometer reading in short blocks is regressed on each gyro axis' share of that
//! prediction; a coefficient near +1 is a gyro that agrees with the accelerometer, near -1 one
//! whose axis is flipped. The accelerometer's offset is removed first (it would otherwise turn
//! with the rate as if it were gravity's). A session that never tilts (turns about the
//! vertical, no moves between faces) cannot tell, nor can one whose hand accelerates the unit
//! more than gravity moves in it (the coefficient then is far from both +1 and -1): the turns'
//! sense then stays the gyro's.

use imu_model::Vec3;
use imu_model::nalgebra::{Matrix3, Vector3};

use crate::ImuSeries;

/// Length of a block whose accelerometer change is regressed, s: long enough for a rotation
/// to move gravity by more than the noise, short enough that the small-angle step holds.
const BLOCK_S: f64 = 0.05;
/// A block whose accelerometer changes by more than this beyond what a rotation of the block
/// could explain is no rotation (parts joined with no motion, a knock), m/s^2.
const JUMP_MARGIN_M_S2: f64 = 3.0;
/// Standard errors by which a coefficient must be negative to call its axis flipped.
const FLIP_SIGMAS: f64 = 5.0;
/// How far from -1 a flipped axis' coefficient may be: farther, the motion is not the pure
/// rotation the regression models (a hand's linear acceleration) and says nothing.
const FLIP_TOLERANCE: f64 = 0.5;

/// What gravity says of each gyro axis' sign.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignCheck {
    /// Per axis: the regression coefficient (+1 agrees, -1 flipped) and its standard error;
    /// None when the samples given do not tilt the unit about that axis.
    pub coefficient: [Option<(f64, f64)>; 3],
}

impl SignCheck {
    /// The axes whose sign gravity says is flipped (the coefficient more than
    /// [`FLIP_SIGMAS`] standard errors below zero and within [`FLIP_TOLERANCE`] of -1).
    pub fn flipped(&self) -> Vec<usize> {
        (0..3)
            .filter(|&a| {
                self.coefficient[a].is_some_and(|(k, se)| {
                    k < 0.0 && -k > FLIP_SIGMAS * se && (k + 1.0).abs() < FLIP_TOLERANCE
                })
            })
            .collect()
    }
}

/// The check over the samples `moving` (ranges of `series` where the unit moves), the gyro's
/// reading at rest `rest` and the accelerometer's offset `accel_offset` removed. Blocks that
/// straddle two labelled parts are left out.
pub fn check_sign(
    series: &ImuSeries,
    moving: &[std::ops::Range<usize>],
    rest: Vec3,
    accel_offset: Vec3,
) -> SignCheck {
    let rate_hz = series.sample_rate_hz();
    let block = ((BLOCK_S * rate_hz).round() as usize).max(1);
    let mut xtx = Matrix3::<f64>::zeros();
    let mut xty = Vector3::<f64>::zeros();
    let mut rows: Vec<(Matrix3<f64>, Vec3)> = Vec::new();
    let same_part = |i: usize, j: usize| {
        series
            .labels
            .as_ref()
            .is_none_or(|l| l.per_sample[i] == l.per_sample[j])
    };
    for r in moving {
        let mut i0 = r.start;
        while i0 + block < r.end {
            let i1 = i0 + block;
            // Column a: the change of f that the rate about axis a predicts over the block.
            let mut x = Matrix3::<f64>::zeros();
            for k in i0..i1 {
                let dt = series.t_s[k + 1] - series.t_s[k];
                let f = Vec3::from(series.accel_m_s2[k]) - accel_offset;
                let w = Vec3::from(series.gyro_rad_s[k]) - rest;
                for a in 0..3 {
                    let mut e = Vec3::zeros();
                    e[a] = 1.0;
                    let col = -w[a] * e.cross(&f) * dt;
                    for c in 0..3 {
                        x[(c, a)] += col[c];
                    }
                }
            }
            let y = Vec3::from(series.accel_m_s2[i1]) - Vec3::from(series.accel_m_s2[i0]);
            let explained: f64 = (0..3).map(|a| x.column(a).norm()).sum();
            if same_part(i0, i1) && y.norm() <= explained + JUMP_MARGIN_M_S2 {
                xtx += x.transpose() * x;
                xty += x.transpose() * y;
                rows.push((x, y));
            }
            i0 = i1;
        }
    }
    let mut coefficient = [None; 3];
    let dof = (3 * rows.len()).saturating_sub(3);
    let Some(inv) = xtx.try_inverse() else {
        return SignCheck { coefficient };
    };
    if dof == 0 {
        return SignCheck { coefficient };
    }
    let k = inv * xty;
    let ss: f64 = rows.iter().map(|(x, y)| (y - x * k).norm_squared()).sum();
    let s2 = ss / dof as f64;
    for a in 0..3 {
        // An axis the samples do not tilt about has no information: its diagonal of X^T X is
        // negligible next to the others'.
        let info = xtx[(a, a)];
        let most = (0..3).map(|b| xtx[(b, b)]).fold(0.0, f64::max);
        if info > 1e-9 * most && info > 0.0 {
            coefficient[a] = Some((k[a], (s2 * inv[(a, a)]).sqrt()));
        }
    }
    SignCheck { coefficient }
}

#[cfg(test)]
mod tests {
    use super::*;
    use imu_model::nalgebra::{Rotation3, Unit};

    /// A unit tilted 5 degrees off vertical turned once about its z axis, and then tipped 90
    /// degrees about x: gravity precesses and then moves, so every axis' sign shows.
    fn session(sign: [f64; 3]) -> ImuSeries {
        let rate_hz = 100.0;
        let mut s = ImuSeries {
            origin: "synthetic".into(),
            ..ImuSeries::default()
        };
        let mut q = Rotation3::from_axis_angle(&Vector3::x_axis(), 5f64.to_radians());
        let g = Vec3::new(0.0, 0.0, 9.8);
        let mut moves: Vec<(Unit<Vec3>, f64)> = vec![(Vector3::z_axis(), 90f64.to_radians()); 400];
        moves.extend(vec![(Vector3::x_axis(), 45f64.to_radians()); 200]);
        moves.extend(vec![(Vector3::y_axis(), 30f64.to_radians()); 200]);
        for (k, (axis, rate)) in moves.iter().enumerate() {
            s.t_s.push(k as f64 / rate_hz);
            s.accel_m_s2.push((q.inverse() * g).into());
            let w = axis.into_inner() * *rate;
            s.gyro_rad_s.push(std::array::from_fn(|a| sign[a] * w[a]));
            q *= Rotation3::from_scaled_axis(w / rate_hz);
        }
        s
    }

    #[test]
    fn gravity_tells_a_flipped_gyro_axis() {
        let all = [std::ops::Range { start: 0, end: 799 }];
        let right = check_sign(&session([1.0; 3]), &all, Vec3::zeros(), Vec3::zeros());
        for a in 0..3 {
            let (k, se) = right.coefficient[a].unwrap();
            assert!((k - 1.0).abs() < 0.1 && se < 0.05, "axis {a}: {k} +/- {se}");
        }
        assert!(right.flipped().is_empty());
        let z = check_sign(
            &session([1.0, 1.0, -1.0]),
            &all,
            Vec3::zeros(),
            Vec3::zeros(),
        );
        assert_eq!(z.flipped(), vec![2], "{z:?}");
        let every = check_sign(&session([-1.0; 3]), &all, Vec3::zeros(), Vec3::zeros());
        assert_eq!(every.flipped(), vec![0, 1, 2], "{every:?}");
        // An offset on the accelerometer is gravity's no more once removed.
        let mut offset = session([-1.0; 3]);
        let b = Vec3::new(0.3, -0.2, 0.25);
        offset
            .accel_m_s2
            .iter_mut()
            .for_each(|a| *a = (Vec3::from(*a) + b).into());
        let removed = check_sign(&offset, &all, Vec3::zeros(), b);
        assert_eq!(removed.flipped(), vec![0, 1, 2]);
        for a in 0..3 {
            let (k, _) = removed.coefficient[a].unwrap();
            let (want, _) = every.coefficient[a].unwrap();
            assert!((k - want).abs() < 1e-9, "axis {a}: {k} vs {want}");
        }
        // A coefficient far from both signs is motion the regression does not model: no call.
        let wild = SignCheck {
            coefficient: [Some((-4.5, 0.8)), Some((-1.1, 0.1)), None],
        };
        assert_eq!(wild.flipped(), vec![1]);
        // A unit that does not move says nothing.
        let mut still = session([1.0; 3]);
        still.gyro_rad_s.iter_mut().for_each(|w| *w = [0.0; 3]);
        let f = still.accel_m_s2[0];
        still.accel_m_s2.iter_mut().for_each(|a| *a = f);
        assert_eq!(
            check_sign(&still, &all, Vec3::zeros(), Vec3::zeros()).coefficient,
            [None; 3]
        );
    }
}
