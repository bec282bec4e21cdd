//! The closed-form start of the reference-free accel fit: an axis-aligned ellipsoid through the
//! still poses' mean specific forces gives each axis's offset (its centre) and scale (its
//! semi-axis over g), so that raw data with offsets of a g or more and scale errors of several
//! percent start next to the answer instead of at zero (where the magnitude fit can diverge).

use imu_model::Vec3;
use imu_model::nalgebra::DMatrix;

/// Offsets and scale errors read off the ellipsoid through the poses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct EllipsoidStart {
    /// The ellipsoid's centre: each axis's offset, m/s^2.
    pub(super) bias_m_s2: Vec3,
    /// Each semi-axis over g, minus 1: the scale error (the model's `(1 + s)`).
    pub(super) scale: Vec3,
}

/// The axis-aligned ellipsoid `sum_i a_i u_i^2 + b_i u_i + d = 0` (u = measured / g) through
/// the pose means in the least-squares sense (the coefficient vector of unit length that
/// minimises the algebraic residual: the right singular vector of the smallest singular
/// value, which, unlike fixing `d = -1`, also works when the offset puts the origin outside
/// or on the ellipsoid). None with fewer than 7 poses, poses that do not span the three axes
/// (the smallest singular value not separated from the next), or a fit that is not an
/// ellipsoid of plausible size (scale errors beyond +-50 %); then the fit starts from the
/// model as given.
pub(super) fn ellipsoid_start(measured: &[Vec3], g_m_s2: f64) -> Option<EllipsoidStart> {
    if measured.len() < 7 || g_m_s2 <= 0.0 {
        return None;
    }
    // In units of g the coefficients are of order one: the matrix stays well scaled.
    let design = DMatrix::from_fn(measured.len(), 7, |r, c| {
        let u = measured[r] / g_m_s2;
        match c {
            0..=2 => u[c] * u[c],
            3..=5 => u[c - 3],
            _ => 1.0,
        }
    });
    let svd = design.svd(false, true);
    let v_t = svd.v_t?;
    let sv = &svd.singular_values;
    let mut order: Vec<usize> = (0..sv.len()).collect();
    order.sort_by(|&i, &j| sv[i].total_cmp(&sv[j]));
    // A second (near-)null direction: the poses leave the ellipsoid undetermined.
    if sv[order[1]] <= 1e-9 * sv[order[6]] {
        return None;
    }
    let mut coef: Vec<f64> = v_t.row(order[0]).iter().copied().collect();
    if coef[0] < 0.0 {
        coef.iter_mut().for_each(|c| *c = -*c);
    }
    let a = Vec3::new(coef[0], coef[1], coef[2]);
    let b = Vec3::new(coef[3], coef[4], coef[5]);
    if !a.iter().all(|v| v.is_finite() && *v > 0.0) {
        return None;
    }
    // sum a_i (u_i - centre_i)^2 = sum a_i centre_i^2 - d = k.
    let centre = -b.component_div(&a) / 2.0;
    let k = a.dot(&centre.component_mul(&centre)) - coef[6];
    let semi_axis = a.map(|ai| (k / ai).sqrt());
    let scale = semi_axis.add_scalar(-1.0);
    (k > 0.0 && scale.iter().all(|s| s.is_finite() && s.abs() < 0.5)).then(|| EllipsoidStart {
        bias_m_s2: centre * g_m_s2,
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_offsets_and_scales_of_an_axis_aligned_sensor() {
        let g = 9.80665;
        let bias = Vec3::new(9.5, -6.2, 3.9);
        let scale = Vec3::new(0.048, -0.035, 0.021);
        let dirs = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.6, 0.0, 0.8],
            [0.0, -0.8, 0.6],
        ];
        let measured: Vec<Vec3> = dirs
            .iter()
            .map(|d| (Vec3::from(*d) * g).component_mul(&scale.add_scalar(1.0)) + bias)
            .collect();
        let s = ellipsoid_start(&measured, g).unwrap();
        assert!((s.bias_m_s2 - bias).norm() < 1e-9, "{s:?}");
        assert!((s.scale - scale).norm() < 1e-12, "{s:?}");
        // Poses about one axis only: no ellipsoid.
        assert_eq!(ellipsoid_start(&measured[..6], g), None);
        let flat: Vec<Vec3> = (0..8)
            .map(|i| {
                let a = i as f64 * 0.7;
                Vec3::new(a.cos(), a.sin(), 0.0) * g
            })
            .collect();
        assert_eq!(ellipsoid_start(&flat, g), None);
    }
}
