//! The timeline builder the compilation appends segments with, and its small helpers.

use super::*;

pub(super) fn axis_name(v: Vector3<f64>) -> String {
    let names = ["x", "y", "z"];
    let i = v.iamax();
    if (v.norm() - v[i].abs()).abs() < 1e-12 {
        format!("{}{}", if v[i] < 0.0 { "-" } else { "+" }, names[i])
    } else {
        format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
    }
}

/// A uniformly distributed random rotation (Shoemake's method).
pub(super) fn random_orientation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    UnitQuaternion::from_quaternion(imu_model::nalgebra::Quaternion::new(
        b * (tau * u3).cos(),
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
    ))
}

/// Accumulates phases while tracking the orientation and time at the end of the last one.
pub(super) struct Builder {
    pub(super) phases: Vec<Phase>,
    pub(super) segments: Vec<SegmentInfo>,
    pub(super) t_s: f64,
    pub(super) q: UnitQuaternion<f64>,
    pub(super) table_angle_rad: f64,
    pub(super) gravity_m_s2: f64,
}

impl Builder {
    pub(super) fn new_segment(
        &mut self,
        kind: &str,
        label: &str,
        axis: Option<Vector3<f64>>,
        rate: Option<f64>,
    ) -> u32 {
        let index = self.segments.len() as u32;
        let g_dir = self.q.inverse_transform_vector(&-Vector3::z());
        self.segments.push(SegmentInfo {
            index,
            kind: kind.to_string(),
            label: label.to_string(),
            start_s: self.t_s,
            end_s: None,
            gravity_dir_sensor: g_dir,
            axis_sensor: axis,
            table_rate_rad_s: rate,
            part: None,
        });
        let _ = self.gravity_m_s2;
        index
    }

    /// Puts the last segment made into the labelled session's part `part`.
    pub(super) fn set_part(&mut self, part: &Option<String>) {
        if let Some(s) = self.segments.last_mut() {
            s.part.clone_from(part);
        }
    }

    pub(super) fn end_segment(&mut self) {
        if let Some(s) = self.segments.last_mut() {
            s.end_s = self.t_s.is_finite().then_some(self.t_s);
        }
    }

    pub(super) fn push(
        &mut self,
        segment: u32,
        axis: Vector3<f64>,
        rate0: f64,
        accel: f64,
        duration_s: f64,
        impacts: Option<ImpactTrain>,
    ) {
        let phase = Phase {
            start_s: self.t_s,
            duration_s,
            segment,
            q0: self.q,
            axis_sensor: Unit::new_normalize(axis),
            rate0_rad_s: rate0,
            accel_rad_s2: accel,
            table_angle0_rad: self.table_angle_rad,
            impacts,
        };
        if duration_s.is_finite() {
            let angle = rate0 * duration_s + 0.5 * accel * duration_s * duration_s;
            self.q = phase.q0 * UnitQuaternion::from_axis_angle(&phase.axis_sensor, angle);
            self.table_angle_rad += angle;
        }
        self.t_s += duration_s;
        self.phases.push(phase);
    }

    pub(super) fn hold(
        &mut self,
        duration_s: f64,
        kind: &str,
        label: &str,
        impacts: Option<ImpactTrain>,
    ) {
        let seg = self.new_segment(kind, label, None, None);
        self.push(seg, Vector3::z(), 0.0, 0.0, duration_s, impacts);
        self.end_segment();
    }

    /// Rotates by `angle_rad` about a sensor axis with a triangular rate profile.
    pub(super) fn rotate(
        &mut self,
        axis: Vector3<f64>,
        angle_rad: f64,
        duration_s: f64,
        label: &str,
    ) {
        let seg = self.new_segment("move", label, Some(axis), None);
        let half = duration_s / 2.0;
        let accel = angle_rad / (half * half);
        self.push(seg, axis, 0.0, accel, half, None);
        self.push(seg, axis, accel * half, -accel, half, None);
        self.end_segment();
    }

    pub(super) fn move_to(&mut self, target: UnitQuaternion<f64>, duration_s: f64, label: &str) {
        let delta = self.q.inverse() * target;
        if let Some((axis, angle)) = delta.axis_angle()
            && angle > 1e-12
        {
            self.rotate(axis.into_inner(), angle, duration_s, label);
        }
        // Land exactly on the target so that numerical drift never accumulates over many moves.
        self.q = target;
    }

    pub(super) fn ramp(
        &mut self,
        axis: Vector3<f64>,
        from: f64,
        to: f64,
        accel_mag: f64,
        label: &str,
    ) {
        if (to - from).abs() < 1e-15 {
            return;
        }
        let seg = self.new_segment("move", label, Some(axis), None);
        let accel = accel_mag.copysign(to - from);
        self.push(seg, axis, from, accel, (to - from) / accel, None);
        self.end_segment();
    }

    pub(super) fn spin(&mut self, axis: Vector3<f64>, rate: f64, duration_s: f64, label: &str) {
        let kind = if rate == 0.0 { "static" } else { "rate" };
        let seg = self.new_segment(kind, label, Some(axis), Some(rate));
        self.push(seg, axis, rate, 0.0, duration_s, None);
        self.end_segment();
    }
}
