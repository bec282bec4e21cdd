//! From a scenario to the analytic motion timeline: Earth's rate at the latitude, the segments
//! in order, random poses from the seed.

use super::*;
use crate::tremor::Tremor;

impl Scenario {
    /// Earth's rotation in East-North-Up at the scenario latitude, rad/s.
    pub fn earth_rate_enu_rad_s(&self) -> Vector3<f64> {
        let (up_rad_s, north_rad_s) = imu_model::earth::earth_rate_split_rad_s(self.latitude_deg);
        Vector3::new(0.0, north_rad_s, up_rad_s)
    }

    /// Builds the motion timeline. `seed` drives the random poses and, for a hand-held
    /// scenario, the tilts of its poses and its tremor, and the random link dropouts (each
    /// from its own stream, so a scenario without `[hand]` or dropouts is unchanged).
    pub fn compile(&self, seed: u64) -> Timeline {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_0f7a_61e5);
        let mut tilts = Tilts {
            max_rad: self.hand.tilt_noise_deg.to_radians(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x7117_0ff5_e7e7),
        };
        let targets: Vec<Option<UnitQuaternion<f64>>> = self
            .segments
            .iter()
            .map(|seg| match seg {
                SegmentSpec::Static {
                    orientation: Some(o),
                    ..
                } => Some(tilts.apply(o.enu_from_sensor().expect("validated"))),
                _ => None,
            })
            .collect();
        let mut b = self.start_builder(targets.first().copied().flatten());
        for (i, seg) in self.segments.iter().enumerate() {
            b.table_angle_rad = 0.0;
            let target = targets[i];
            self.compile_segment(&mut b, i + 1, seg, target, (&mut rng, &mut tilts));
        }
        if self.hand.tremor_deg > 0.0 {
            // A trembling hand's still poses are still only nominally: `held`, not `static`
            // (whose sensor direction of gravity never changes).
            for seg in b.segments.iter_mut().filter(|s| s.kind == "static") {
                seg.kind = "held".into();
            }
        }
        let timeline = Timeline::new(
            b.phases,
            b.segments,
            self.gravity_m_s2,
            self.earth_rate_enu_rad_s(),
            Vector3::from(self.mag_field_enu_gauss),
        );
        let dropouts = self.dropouts(seed, timeline.duration_s());
        let timeline = timeline.with_dropouts(dropouts);
        if self.hand.tremor_deg > 0.0 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7e3e_0b1e_5eed);
            let tremor = Tremor::new(
                self.hand.tremor_deg.to_radians(),
                self.hand.tremor_band_hz,
                &mut rng,
            );
            return timeline.with_tremor(tremor);
        }
        timeline
    }

    /// An empty timeline at the starting orientation: level (roll = pitch = yaw = 0: x north,
    /// y east, z down) unless the first segment is a static one at `first` (its attitude,
    /// tilted), in which case the sensor starts there without a move.
    fn start_builder(&self, first: Option<UnitQuaternion<f64>>) -> Builder {
        let mut b = Builder {
            phases: Vec::new(),
            segments: Vec::new(),
            t_s: 0.0,
            q: UnitQuaternion::identity(),
            table_angle_rad: 0.0,
            gravity_m_s2: self.gravity_m_s2,
        };
        b.q = first.unwrap_or_else(enu_from_ned);
        b
    }

    /// Appends segment number `n` (1-based) to the timeline; `target` is a static segment's
    /// attitude (tilted), `rng` draws random poses and `tilts` tilts them.
    fn compile_segment(
        &self,
        b: &mut Builder,
        n: usize,
        seg: &SegmentSpec,
        target: Option<UnitQuaternion<f64>>,
        (rng, tilts): (&mut ChaCha8Rng, &mut Tilts),
    ) {
        match seg {
            SegmentSpec::Static {
                duration_s,
                move_s,
                label,
                part,
                ..
            } => {
                if let Some(target) = target {
                    b.move_to(
                        target,
                        move_s.unwrap_or(self.transition_s),
                        &format!("move to segment {n}"),
                    );
                }
                let label = label.clone().unwrap_or_else(|| format!("static {n}"));
                b.hold(duration_s.unwrap_or(f64::INFINITY), "static", &label, None);
                b.set_part(part);
            }
            SegmentSpec::IndexTable {
                axis,
                step_deg,
                positions,
                dwell_s,
                move_s,
            } => index_table(b, n, axis.0, *step_deg, *positions, *dwell_s, *move_s),
            SegmentSpec::RateSteps {
                axis,
                rates_deg_s,
                dwell_s,
                accel_deg_s2,
            } => rate_steps(b, n, axis.0, rates_deg_s, *dwell_s, *accel_deg_s2),
            SegmentSpec::Rotate {
                axis,
                angle_deg,
                duration_s,
                wobble_deg,
                part,
            } => {
                let label = format!(
                    "segment {n} rotate {angle_deg} deg about {}",
                    axis_name(axis.0)
                );
                if *wobble_deg == 0.0 {
                    b.rotate(axis.0, angle_deg.to_radians(), *duration_s, &label);
                } else {
                    // A hand's turn wobbles: its axis tipped towards the next sensor axis (x to
                    // y, y to z, z to x) for the first half, away from it for the second.
                    let next = Vector3::new(axis.0[2], axis.0[0], axis.0[1]);
                    let about = Unit::new_normalize(axis.0.cross(&next));
                    for tip_deg in [*wobble_deg, -*wobble_deg] {
                        let tip = Rotation3::from_axis_angle(&about, tip_deg.to_radians());
                        b.rotate(
                            tip * axis.0,
                            angle_deg.to_radians() / 2.0,
                            duration_s / 2.0,
                            &label,
                        );
                        b.set_part(part);
                    }
                }
                b.set_part(part);
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
            } => random_poses(b, n, (*count, *dwell_s, *move_s), rng, tilts),
        }
    }
}

/// The tilt noise of held poses: each attitude off its nominal by a rotation about a random
/// horizontal axis by an angle uniform in +-`max_rad`.
pub(super) struct Tilts {
    max_rad: f64,
    rng: ChaCha8Rng,
}

impl Tilts {
    /// `nominal` (`enu_from_sensor`) tilted; unchanged when there is no tilt noise.
    fn apply(&mut self, nominal: UnitQuaternion<f64>) -> UnitQuaternion<f64> {
        if self.max_rad <= 0.0 {
            return nominal;
        }
        let azimuth = self.rng.random_range(0.0..std::f64::consts::TAU);
        let angle = self.rng.random_range(-self.max_rad..=self.max_rad);
        let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
        UnitQuaternion::from_axis_angle(&axis, angle) * nominal
    }
}

/// `count` random orientations (tilted by `tilts`), each reached in `move_s` and held for
/// `dwell_s`.
fn random_poses(
    b: &mut Builder,
    n: usize,
    (count, dwell_s, move_s): (u32, f64, f64),
    rng: &mut ChaCha8Rng,
    tilts: &mut Tilts,
) {
    for p in 0..count {
        let target = tilts.apply(random_orientation(rng));
        b.move_to(
            target,
            move_s,
            &format!("segment {n} move to pose {}", p + 1),
        );
        b.hold(
            dwell_s,
            "static",
            &format!("segment {n} pose {}", p + 1),
            None,
        );
    }
}

/// An index table: `positions` dwells `step_deg` apart about `axis`.
fn index_table(
    b: &mut Builder,
    n: usize,
    axis: Vector3<f64>,
    step_deg: f64,
    positions: u32,
    dwell_s: f64,
    move_s: f64,
) {
    for p in 0..positions {
        let angle = step_deg * p as f64;
        b.hold(
            dwell_s,
            "static",
            &format!(
                "segment {n} position {} ({angle} deg about {})",
                p + 1,
                axis_name(axis)
            ),
            None,
        );
        if p + 1 < positions {
            b.rotate(
                axis,
                step_deg.to_radians(),
                move_s,
                &format!("segment {n} step {}", p + 1),
            );
        }
    }
}

/// Rate-table plateaus about `axis`, ramping between them and back to rest.
fn rate_steps(
    b: &mut Builder,
    n: usize,
    axis: Vector3<f64>,
    rates_deg_s: &[f64],
    dwell_s: f64,
    accel_deg_s2: f64,
) {
    let accel = accel_deg_s2.to_radians();
    let mut rate = 0.0;
    for r in rates_deg_s {
        let target = r.to_radians();
        b.ramp(
            axis,
            rate,
            target,
            accel,
            &format!("segment {n} ramp to {r} deg/s"),
        );
        b.spin(
            axis,
            target,
            dwell_s,
            &format!("segment {n} rate {r} deg/s"),
        );
        rate = target;
    }
    b.ramp(axis, rate, 0.0, accel, &format!("segment {n} stop"));
}
