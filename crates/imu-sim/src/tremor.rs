//! Hand tremor: a small band-limited angular motion on top of a timeline's motion, for
//! hand-held scenarios (the scenario's `[hand]` table).
//!
//! The tremor angle `theta(t)` (a rotation vector in the sensor frame) is a sum of sinusoids per
//! axis with frequencies drawn uniformly in the band and random phases, seeded; its RMS per
//! axis is the scenario's `tremor-deg`. The sensor's orientation is the timeline's followed by
//! `exp(theta)`, so every output follows exactly from that one orientation: the rate is the
//! table rate seen in the trembling frame plus `J_r(theta) theta'` (the right Jacobian of SO(3)),
//! gravity, Earth's rate and the magnetic field are rotated with it. The angular acceleration
//! drops the `d/dt J_r` term of second order in the tremor angle (|theta| |theta'|^2, under
//! 1e-3 rad/s^2 at a few tenths of a degree).

use imu_model::nalgebra::{Matrix3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::motion::MotionState;

/// Sinusoids per axis: enough for a band-limited, non-periodic-looking motion.
const COMPONENTS: usize = 6;

/// One sinusoid of one axis: `amplitude sin(omega t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sine {
    amplitude_rad: f64,
    omega_rad_s: f64,
    phase_rad: f64,
}

/// The tremor of one scenario run.
#[derive(Debug, Clone, PartialEq)]
pub struct Tremor {
    axes: [Vec<Sine>; 3],
}

impl Tremor {
    /// A tremor of `rms_rad` per axis with frequencies in `band_hz`, drawn from `rng`.
    pub fn new(rms_rad: f64, band_hz: [f64; 2], rng: &mut ChaCha8Rng) -> Self {
        // The RMS of n unit sinusoids at distinct frequencies is sqrt(n / 2).
        let amplitude_rad = rms_rad * (2.0 / COMPONENTS as f64).sqrt();
        let axes = std::array::from_fn(|_| {
            (0..COMPONENTS)
                .map(|_| Sine {
                    amplitude_rad,
                    omega_rad_s: std::f64::consts::TAU * rng.random_range(band_hz[0]..band_hz[1]),
                    phase_rad: rng.random_range(0.0..std::f64::consts::TAU),
                })
                .collect()
        });
        Self { axes }
    }

    /// The tremor angle and its first two derivatives at `t_s`.
    fn angle(&self, t_s: f64) -> [Vector3<f64>; 3] {
        let mut out = [Vector3::zeros(); 3];
        for (axis, sines) in self.axes.iter().enumerate() {
            for s in sines {
                let (sin, cos) = (s.omega_rad_s * t_s + s.phase_rad).sin_cos();
                out[0][axis] += s.amplitude_rad * sin;
                out[1][axis] += s.amplitude_rad * s.omega_rad_s * cos;
                out[2][axis] -= s.amplitude_rad * s.omega_rad_s * s.omega_rad_s * sin;
            }
        }
        out
    }

    /// The state at `t_s` with the tremor on top of `state` (the timeline's motion).
    pub fn apply(&self, t_s: f64, state: &mut MotionState) {
        let [theta, theta_dot, theta_ddot] = self.angle(t_s);
        let r = UnitQuaternion::from_scaled_axis(theta);
        let jr = right_jacobian(&theta);
        let w_tremor = jr * theta_dot;
        let a_tremor = jr * theta_ddot;
        let rate_seen = r.inverse_transform_vector(&state.angular_rate_rad_s);
        state.angular_accel_rad_s2 = r.inverse_transform_vector(&state.angular_accel_rad_s2)
            - w_tremor.cross(&rate_seen)
            + a_tremor;
        state.angular_rate_rad_s = rate_seen + w_tremor;
        state.enu_from_sensor *= r;
        state.specific_force_m_s2 = r.inverse_transform_vector(&state.specific_force_m_s2);
        state.mag_field_gauss = r.inverse_transform_vector(&state.mag_field_gauss);
    }
}

/// The right Jacobian of SO(3) at rotation vector `theta`: the body rate of `exp(theta(t))` is
/// `J_r(theta) theta'`.
fn right_jacobian(theta: &Vector3<f64>) -> Matrix3<f64> {
    let phi = theta.norm();
    let k = theta.cross_matrix();
    if phi < 1e-8 {
        return Matrix3::identity() - 0.5 * k;
    }
    Matrix3::identity() - (1.0 - phi.cos()) / (phi * phi) * k
        + (phi - phi.sin()) / (phi * phi * phi) * k * k
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn still_state() -> MotionState {
        MotionState {
            segment: 0,
            enu_from_sensor: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
            specific_force_m_s2: Vector3::new(0.0, 0.0, -9.8),
            angular_rate_rad_s: Vector3::new(0.2, -0.1, 0.05),
            angular_accel_rad_s2: Vector3::zeros(),
            mag_field_gauss: Vector3::new(0.2, 0.0, 0.4),
            table_angle_rad: 0.0,
            table_rate_rad_s: 0.0,
        }
    }

    /// The rate the state reports is the derivative of the orientation it reports (a tremor
    /// of 2 degrees RMS, ten times the scenarios', so the nonlinear terms matter), and the
    /// angle has the RMS asked for.
    #[test]
    fn rate_is_the_derivative_of_the_orientation() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let tremor = Tremor::new(2f64.to_radians(), [4.0, 12.0], &mut rng);
        // The underlying motion: a constant body rate from a fixed start, gravity and the
        // field fixed in the level frame.
        let untrembling = |t: f64| {
            let mut s = still_state();
            let (g, m) = (
                s.enu_from_sensor.transform_vector(&s.specific_force_m_s2),
                s.enu_from_sensor.transform_vector(&s.mag_field_gauss),
            );
            s.enu_from_sensor *= UnitQuaternion::from_scaled_axis(s.angular_rate_rad_s * t);
            s.specific_force_m_s2 = s.enu_from_sensor.inverse_transform_vector(&g);
            s.mag_field_gauss = s.enu_from_sensor.inverse_transform_vector(&m);
            s
        };
        let base = |t: f64| {
            let mut s = untrembling(t);
            tremor.apply(t, &mut s);
            s
        };
        let h = 1e-5;
        let mut sum_sq = Vector3::zeros();
        let n = 4000;
        for i in 0..n {
            let t = i as f64 * 0.0025;
            let (a, b, s) = (base(t - h), base(t + h), base(t));
            let dq = a.enu_from_sensor.inverse() * b.enu_from_sensor;
            let w_fd = dq.scaled_axis() / (2.0 * h);
            assert!(
                (w_fd - s.angular_rate_rad_s).norm() < 1e-6 * (1.0 + w_fd.norm()),
                "t {t}: {w_fd:?} vs {:?}",
                s.angular_rate_rad_s
            );
            let a_fd = (b.angular_rate_rad_s - a.angular_rate_rad_s) / (2.0 * h);
            // Up to the dropped second-order term.
            assert!(
                (a_fd - s.angular_accel_rad_s2).norm() < 0.02 * a_fd.norm() + 0.05,
                "t {t}: {a_fd:?} vs {:?}",
                s.angular_accel_rad_s2
            );
            // Gravity and the field stay fixed in the level frame.
            let u = untrembling(t);
            let level = |s: &MotionState| {
                (
                    s.enu_from_sensor.transform_vector(&s.specific_force_m_s2),
                    s.enu_from_sensor.transform_vector(&s.mag_field_gauss),
                )
            };
            let ((g, m), (g0, m0)) = (level(&s), level(&u));
            assert!((g - g0).norm() < 1e-9 && (m - m0).norm() < 1e-12);
            let [theta, _, _] = tremor.angle(t);
            sum_sq += theta.component_mul(&theta);
        }
        for axis in 0..3 {
            let rms_deg = (sum_sq[axis] / n as f64).sqrt().to_degrees();
            assert!((rms_deg / 2.0 - 1.0).abs() < 0.3, "axis {axis}: {rms_deg}");
        }
    }
}
