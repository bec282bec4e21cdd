//! From a scenario to the analytic motion timeline: Earth's rate at the latitude, the segments
//! in order, random poses from the seed.

use super::*;

impl Scenario {
    /// Earth's rotation in East-North-Up at the scenario latitude, rad/s.
    pub fn earth_rate_enu_rad_s(&self) -> Vector3<f64> {
        let (up_rad_s, north_rad_s) = imu_model::earth::earth_rate_split_rad_s(self.latitude_deg);
        Vector3::new(0.0, north_rad_s, up_rad_s)
    }

    /// Builds the motion timeline. `seed` drives the random poses.
    pub fn compile(&self, seed: u64) -> Timeline {
        let mut b = Builder {
            phases: Vec::new(),
            segments: Vec::new(),
            t_s: 0.0,
            q: UnitQuaternion::identity(),
            table_angle_rad: 0.0,
            gravity_m_s2: self.gravity_m_s2,
        };
        // The sensor starts level (roll = pitch = yaw = 0: x north, y east, z down) unless the
        // first segment says otherwise, in which case it starts there without a move.
        b.q = enu_from_ned();
        if let Some(SegmentSpec::Static {
            orientation: Some(o),
            ..
        }) = self.segments.first()
        {
            b.q = o.enu_from_sensor().expect("validated");
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_0f7a_61e5);
        for (i, seg) in self.segments.iter().enumerate() {
            b.table_angle_rad = 0.0;
            let n = i + 1;
            match seg {
                SegmentSpec::Static {
                    orientation,
                    duration_s,
                    move_s,
                    label,
                } => {
                    if let Some(o) = orientation {
                        let target = o.enu_from_sensor().expect("validated");
                        b.move_to(
                            target,
                            move_s.unwrap_or(self.transition_s),
                            &format!("move to segment {n}"),
                        );
                    }
                    let label = label.clone().unwrap_or_else(|| format!("static {n}"));
                    b.hold(duration_s.unwrap_or(f64::INFINITY), "static", &label, None);
                }
                SegmentSpec::IndexTable {
                    axis,
                    step_deg,
                    positions,
                    dwell_s,
                    move_s,
                } => {
                    for p in 0..*positions {
                        let angle = step_deg * p as f64;
                        b.hold(
                            *dwell_s,
                            "static",
                            &format!(
                                "segment {n} position {} ({angle} deg about {})",
                                p + 1,
                                axis_name(axis.0)
                            ),
                            None,
                        );
                        if p + 1 < *positions {
                            b.rotate(
                                axis.0,
                                step_deg.to_radians(),
                                *move_s,
                                &format!("segment {n} step {}", p + 1),
                            );
                        }
                    }
                }
                SegmentSpec::RateSteps {
                    axis,
                    rates_deg_s,
                    dwell_s,
                    accel_deg_s2,
                } => {
                    let accel = accel_deg_s2.to_radians();
                    let mut rate = 0.0;
                    for r in rates_deg_s {
                        let target = r.to_radians();
                        b.ramp(
                            axis.0,
                            rate,
                            target,
                            accel,
                            &format!("segment {n} ramp to {r} deg/s"),
                        );
                        b.spin(
                            axis.0,
                            target,
                            *dwell_s,
                            &format!("segment {n} rate {r} deg/s"),
                        );
                        rate = target;
                    }
                    b.ramp(axis.0, rate, 0.0, accel, &format!("segment {n} stop"));
                }
                SegmentSpec::Rotate {
                    axis,
                    angle_deg,
                    duration_s,
                } => {
                    b.rotate(
                        axis.0,
                        angle_deg.to_radians(),
                        *duration_s,
                        &format!(
                            "segment {n} rotate {angle_deg} deg about {}",
                            axis_name(axis.0)
                        ),
                    );
                }
                SegmentSpec::Impacts {
                    axis,
                    count,
                    period_s,
                    peak_g,
                    width_ms,
                } => {
                    let train = ImpactTrain {
                        axis_sensor: axis.0,
                        peak_m_s2: peak_g * self.gravity_m_s2,
                        width_s: width_ms * 1e-3,
                        period_s: *period_s,
                    };
                    b.hold(
                        *count as f64 * period_s,
                        "impacts",
                        &format!("segment {n} impacts along {}", axis_name(axis.0)),
                        Some(train),
                    );
                }
                SegmentSpec::RandomPoses {
                    count,
                    dwell_s,
                    move_s,
                } => {
                    for p in 0..*count {
                        let target = random_orientation(&mut rng);
                        b.move_to(
                            target,
                            *move_s,
                            &format!("segment {n} move to pose {}", p + 1),
                        );
                        b.hold(
                            *dwell_s,
                            "static",
                            &format!("segment {n} pose {}", p + 1),
                            None,
                        );
                    }
                }
            }
        }
        Timeline::new(
            b.phases,
            b.segments,
            self.gravity_m_s2,
            self.earth_rate_enu_rad_s(),
            Vector3::from(self.mag_field_enu_gauss),
        )
    }
}
