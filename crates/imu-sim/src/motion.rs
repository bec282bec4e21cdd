//! The physics: the true motion of the sensor as exact analytic functions of time.
//!
//! A [`Timeline`] is a list of phases, each a rotation about one sensor-fixed table axis with
//! constant angular acceleration (zero for holds and plateaus), so orientation, rate and angular
//! acceleration are exact at any instant with no numerical integration to drift. On top of the
//! table motion come the Earth's rotation (at the scenario latitude), gravity, the magnetic field
//! and optional shock trains, and, for hand-held scenarios, hand tremor (`tremor.rs`).

use imu_model::nalgebra::{Unit, UnitQuaternion, Vector3};

use crate::scenario::LinkDropout;
use crate::tremor::Tremor;

/// A train of half-sine specific-force shocks along a sensor axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpactTrain {
    /// Shock direction in the sensor frame (unit vector).
    pub axis_sensor: Vector3<f64>,
    /// Peak specific force, m/s^2.
    pub peak_m_s2: f64,
    /// Duration of one shock, seconds.
    pub width_s: f64,
    /// Time between shock starts, seconds.
    pub period_s: f64,
}

impl ImpactTrain {
    /// Shock specific force at `tau_s` after the train started, m/s^2.
    fn specific_force(&self, tau_s: f64) -> Vector3<f64> {
        let phase_s = tau_s.rem_euclid(self.period_s);
        if phase_s < self.width_s {
            self.axis_sensor
                * self.peak_m_s2
                * (std::f64::consts::PI * phase_s / self.width_s).sin()
        } else {
            Vector3::zeros()
        }
    }
}

/// One piece of the timeline: rotation about a sensor-fixed axis with constant angular
/// acceleration.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// Scenario time the phase starts, seconds.
    pub start_s: f64,
    /// Duration, seconds (infinite for an endless last hold).
    pub duration_s: f64,
    /// Index of the segment it belongs to.
    pub segment: u32,
    /// Orientation at the start (`enu_from_sensor`).
    pub q0: UnitQuaternion<f64>,
    /// Table axis in the sensor frame.
    pub axis_sensor: Unit<Vector3<f64>>,
    /// Table rate at the start, rad/s.
    pub rate0_rad_s: f64,
    /// Constant table angular acceleration, rad/s^2.
    pub accel_rad_s2: f64,
    /// Table angle at the start, rad.
    pub table_angle0_rad: f64,
    /// Shocks during this phase, if any.
    pub impacts: Option<ImpactTrain>,
}

/// Description of one segment, for the truth file and later plan matching.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentInfo {
    /// Segment index.
    pub index: u32,
    /// `static`, `move`, `rate` or `impacts`; `held` for a still pose held by a trembling
    /// hand (a scenario's `[hand] tremor-deg`): still but for the tremor.
    pub kind: String,
    /// Human-readable label.
    pub label: String,
    /// Start, seconds.
    pub start_s: f64,
    /// End, seconds (`None` if endless).
    pub end_s: Option<f64>,
    /// Unit vector of gravity (down) in the sensor frame at the start.
    pub gravity_dir_sensor: Vector3<f64>,
    /// Table axis (motion segments).
    pub axis_sensor: Option<Vector3<f64>>,
    /// Plateau rate of `rate` segments, rad/s.
    pub table_rate_rad_s: Option<f64>,
    /// The labelled session's part the segment belongs to (a scenario segment's `part`).
    pub part: Option<String>,
}

/// The true state of the sensor at one instant.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionState {
    /// Segment index.
    pub segment: u32,
    /// `enu_from_sensor`.
    pub enu_from_sensor: UnitQuaternion<f64>,
    /// Specific force at the sensor (what an ideal accelerometer reads), sensor frame, m/s^2.
    pub specific_force_m_s2: Vector3<f64>,
    /// Inertial angular rate (table + Earth), sensor frame, rad/s.
    pub angular_rate_rad_s: Vector3<f64>,
    /// Its time derivative, sensor frame, rad/s^2.
    pub angular_accel_rad_s2: Vector3<f64>,
    /// Magnetic field, sensor frame, gauss.
    pub mag_field_gauss: Vector3<f64>,
    /// Table angle within the current segment group, rad.
    pub table_angle_rad: f64,
    /// Table rate, rad/s.
    pub table_rate_rad_s: f64,
}

/// The whole motion of a scenario.
#[derive(Debug, Clone)]
pub struct Timeline {
    phases: Vec<Phase>,
    segments: Vec<SegmentInfo>,
    gravity_m_s2: f64,
    earth_rate_enu_rad_s: Vector3<f64>,
    mag_enu_gauss: Vector3<f64>,
    tremor: Option<Tremor>,
    /// Windows whose data replies the link loses, in time order, not overlapping.
    dropouts: Vec<LinkDropout>,
}

impl Timeline {
    /// Assembles a timeline (see [`crate::scenario::Scenario::compile`]).
    pub fn new(
        phases: Vec<Phase>,
        segments: Vec<SegmentInfo>,
        gravity_m_s2: f64,
        earth_rate_enu_rad_s: Vector3<f64>,
        mag_enu_gauss: Vector3<f64>,
    ) -> Self {
        Self {
            phases,
            segments,
            gravity_m_s2,
            earth_rate_enu_rad_s,
            mag_enu_gauss,
            tremor: None,
            dropouts: Vec::new(),
        }
    }

    /// The same motion with link dropouts (in time order, not overlapping).
    pub fn with_dropouts(mut self, dropouts: Vec<LinkDropout>) -> Self {
        self.dropouts = dropouts;
        self
    }

    /// The link's dropout windows, in time order.
    pub fn dropouts(&self) -> &[LinkDropout] {
        &self.dropouts
    }

    /// True if the link loses the device's data reply at scenario time `t_s`.
    pub fn link_lost_at(&self, t_s: f64) -> bool {
        let i = self.dropouts.partition_point(|d| d.start_s <= t_s);
        i > 0 && self.dropouts[i - 1].contains(t_s)
    }

    /// The same motion with hand tremor on top (see [`Tremor`]).
    pub fn with_tremor(mut self, tremor: Tremor) -> Self {
        self.tremor = Some(tremor);
        self
    }

    /// Total duration, seconds (infinite for an endless scenario).
    pub fn duration_s(&self) -> f64 {
        self.phases.last().map_or(0.0, |p| p.start_s + p.duration_s)
    }

    /// The segments, in order.
    pub fn segments(&self) -> &[SegmentInfo] {
        &self.segments
    }

    /// The phases, in order.
    pub fn phases(&self) -> &[Phase] {
        &self.phases
    }

    /// The true state at scenario time `t_s` (clamped into the timeline).
    pub fn state(&self, t_s: f64) -> MotionState {
        let i = self
            .phases
            .partition_point(|p| p.start_s <= t_s)
            .saturating_sub(1);
        let p = &self.phases[i];
        let tau = (t_s - p.start_s).clamp(0.0, p.duration_s);
        let rate = p.rate0_rad_s + p.accel_rad_s2 * tau;
        let angle = p.rate0_rad_s * tau + 0.5 * p.accel_rad_s2 * tau * tau;
        let q = p.q0 * UnitQuaternion::from_axis_angle(&p.axis_sensor, angle);
        let axis = p.axis_sensor.into_inner();
        let table_rate_s = axis * rate;
        let earth_s = q.inverse_transform_vector(&self.earth_rate_enu_rad_s);
        // d/dt of the Earth rate seen in a frame turning at the table rate.
        let angular_accel = axis * p.accel_rad_s2 - table_rate_s.cross(&earth_s);
        let mut specific_force =
            q.inverse_transform_vector(&Vector3::new(0.0, 0.0, self.gravity_m_s2));
        if let Some(train) = &p.impacts {
            specific_force += train.specific_force(tau);
        }
        let mut state = MotionState {
            segment: p.segment,
            enu_from_sensor: q,
            specific_force_m_s2: specific_force,
            angular_rate_rad_s: earth_s + table_rate_s,
            angular_accel_rad_s2: angular_accel,
            mag_field_gauss: q.inverse_transform_vector(&self.mag_enu_gauss),
            table_angle_rad: p.table_angle0_rad + angle,
            table_rate_rad_s: rate,
        };
        if let Some(tremor) = &self.tremor {
            tremor.apply(t_s, &mut state);
        }
        state
    }
}

#[cfg(test)]
mod tests {
    use crate::scenario::Scenario;
    use imu_model::nalgebra::Vector3;

    fn compile(text: &str) -> super::Timeline {
        Scenario::from_toml_str(text, "t.toml").unwrap().compile(1)
    }

    #[test]
    fn level_at_rest_reads_minus_g_on_z_and_earth_rate() {
        let t = compile("name='t'\nlatitude-deg = 40\n[[segment]]\nkind='static'\nduration-s=10\n");
        let s = t.state(5.0);
        let g = imu_model::units::STANDARD_GRAVITY_M_S2;
        assert!((s.specific_force_m_s2 - Vector3::new(0.0, 0.0, -g)).norm() < 1e-12);
        // x north, z down: Earth rate = (Omega cos L, 0, -Omega sin L).
        let w = imu_model::units::EARTH_RATE_RAD_S;
        let lat = 40f64.to_radians();
        let expect = Vector3::new(w * lat.cos(), 0.0, -w * lat.sin());
        assert!((s.angular_rate_rad_s - expect).norm() < 1e-18);
    }

    #[test]
    fn index_table_visits_gravity_directions_and_integrates_rate() {
        let t = compile(
            "name='t'\n[[segment]]\nkind='static'\norientation={x='north', z='up'}\nduration-s=1\n\
             [[segment]]\nkind='index-table'\naxis='y'\nstep-deg=30\npositions=12\ndwell-s=5\nmove-s=2\n",
        );
        let statics: Vec<_> = t.segments().iter().filter(|s| s.kind == "static").collect();
        assert_eq!(statics.len(), 13);
        for (k, seg) in statics[1..].iter().enumerate() {
            let s = t.state(seg.start_s + 2.5);
            // Rotating about +y by k*30 deg tilts gravity in the x-z plane.
            let a = (30.0 * k as f64).to_radians();
            let f = s.specific_force_m_s2 / imu_model::units::STANDARD_GRAVITY_M_S2;
            assert!(
                (f - Vector3::new(-a.sin(), 0.0, a.cos())).norm() < 1e-9,
                "position {k}: {f:?}"
            );
            assert!((s.table_angle_rad - a).abs() < 1e-9);
        }
        // Numerically integrating the true rate over a move reproduces the step angle.
        let mv = t.segments().iter().find(|s| s.kind == "move").unwrap();
        let (t0, t1) = (mv.start_s, mv.end_s.unwrap());
        let n = 20_000;
        let dt = (t1 - t0) / n as f64;
        let mut angle = 0.0;
        for i in 0..n {
            angle += t.state(t0 + (i as f64 + 0.5) * dt).table_rate_rad_s * dt;
        }
        assert!((angle - 30f64.to_radians()).abs() < 1e-6);
    }

    #[test]
    fn rate_steps_reach_each_plateau_and_stop() {
        let t = compile(
            "name='t'\n[[segment]]\nkind='rate-steps'\naxis='z'\nrates-deg-s=[20, 80, -40]\ndwell-s=4\naccel-deg-s2=40\n\
             [[segment]]\nkind='static'\nduration-s=1\n",
        );
        let plateaus: Vec<_> = t.segments().iter().filter(|s| s.kind == "rate").collect();
        assert_eq!(plateaus.len(), 3);
        for (seg, r) in plateaus.iter().zip([20.0f64, 80.0, -40.0]) {
            let s = t.state(seg.start_s + 1.0);
            assert!((s.table_rate_rad_s - r.to_radians()).abs() < 1e-12);
            // Only the Earth-rate cross term (|w_table x Omega| < 1.1e-4 rad/s^2) remains on a plateau.
            assert!(s.angular_accel_rad_s2.norm() < 1.1e-4);
        }
        let last = t.segments().last().unwrap();
        assert_eq!(t.state(last.start_s + 0.5).table_rate_rad_s, 0.0);
    }

    #[test]
    fn impacts_are_half_sines_along_the_axis() {
        let t = compile(
            "name='t'\n[[segment]]\nkind='impacts'\naxis='-z'\ncount=3\nperiod-s=1\npeak-g=2\nwidth-ms=10\n",
        );
        let g = imu_model::units::STANDARD_GRAVITY_M_S2;
        let peak = t.state(1.005).specific_force_m_s2 - t.state(1.5).specific_force_m_s2;
        assert!((peak - Vector3::new(0.0, 0.0, -2.0 * g)).norm() < 1e-9);
        assert_eq!(
            t.state(1.5).specific_force_m_s2,
            t.state(0.5).specific_force_m_s2
        );
        assert!((t.duration_s() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn random_poses_are_reproducible_per_seed() {
        let text = "name='t'\n[[segment]]\nkind='random-poses'\ncount=5\ndwell-s=1\nmove-s=1\n";
        let s = Scenario::from_toml_str(text, "t.toml").unwrap();
        let (a, b, c) = (s.compile(3), s.compile(3), s.compile(4));
        let at = |t: &super::Timeline| t.state(t.duration_s() - 0.5).specific_force_m_s2;
        assert_eq!(at(&a), at(&b));
        assert!((at(&a) - at(&c)).norm() > 1e-3);
    }
}
