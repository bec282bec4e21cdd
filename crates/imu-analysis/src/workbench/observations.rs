//! Building a workbench: segmenting the recording and turning a reference (or, reference-free,
//! the gravity magnitude, Earth's rate and the moves between poses) into observations.

use super::*;

impl<'a> Workbench<'a> {
    /// Segments `series`, takes the truth from `reference`, measures the noise floors.
    pub fn new(
        series: &'a ImuSeries,
        reference: &Reference,
        opts: DiagnoseOptions,
    ) -> Result<Workbench<'a>, DiagnoseError> {
        let obs = Observations::from_recording(series, reference, &opts.segment, true)?;
        let rate = series.sample_rate_hz();
        let (accel_floor, gyro_floor) = floors(series, &obs, &opts)?;
        let n_of = |v: &[(usize, FitPoint)]| -> Vec<usize> {
            v.iter()
                .map(|(i, _)| obs.segmentation.segments[*i].n)
                .collect()
        };
        let (an, gn) = (n_of(&obs.accel), n_of(&obs.gyro));
        let accel_points = floored_points(&obs.points(Triad::Accel), &accel_floor, rate, &an);
        let gyro_points = floored_points(&obs.points(Triad::Gyro), &gyro_floor, rate, &gn);
        let spectral = [
            spectral_lines(series, &obs, Triad::Accel),
            spectral_lines(series, &obs, Triad::Gyro),
        ];
        Ok(Workbench {
            series,
            accel_index: obs.accel.iter().map(|(i, _)| *i).collect(),
            gyro_index: obs.gyro.iter().map(|(i, _)| *i).collect(),
            obs,
            accel_floor,
            gyro_floor,
            accel_points,
            gyro_points,
            opts,
            spectral,
            mode: Mode::Reference,
            notes: crate::note::Notes::default(),
        })
    }

    /// A workbench without a reference: the unit was held still in many orientations and
    /// turned between them (as for `imu-calibrate --reference-free`).
    ///
    /// - The accel is held against the gravity magnitude at every still pose
    ///   (`g - |corrected mean|`, one residual per pose; its floor is the per-axis floor
    ///   projected on the pose's direction); the rotation gauge is fixed as in the
    ///   reference-free calibration (accel misalignment `xy`, `xz`, `yz` held at 0).
    /// - The gyro offsets (bias, g-sensitivity, temperature, warm-up) are held against the
    ///   still poses, whose true rate is Earth's: its vertical part along the calibrated up
    ///   direction when the latitude is given; the part a heading would fix (horizontal, or all
    ///   of it without a latitude) is an extra noise of each pose mean.
    /// - The gyro gains (scale, misalignment, asymmetry, nonlinearity) are held against the
    ///   rotations integrated over the moves between poses, as `imu-calibrate
    ///   --reference-free` fits them, with the gain effects of the library as candidates; the
    ///   ladder's calibration is that procedure's fit of the final model.
    pub fn reference_free(
        series: &'a ImuSeries,
        gravity_m_s2: Option<f64>,
        latitude_deg: Option<f64>,
        opts: DiagnoseOptions,
    ) -> Result<Workbench<'a>, DiagnoseError> {
        use crate::calibrate::reference_free::local_gravity;
        let segmentation =
            crate::segment::detect(series, &opts.segment).map_err(CalibrateError::from)?;
        let (g_m_s2, gravity_note) = local_gravity(gravity_m_s2, latitude_deg);
        let vertical_rad_s = earth_rate_truth(latitude_deg);
        let poses: Vec<usize> = (0..segmentation.segments.len())
            .filter(|&i| segmentation.segments[i].kind == SegmentKind::Static)
            .collect();
        let dirs: Vec<Vec3> = poses
            .iter()
            .map(|&i| segmentation.segments[i].mean_accel().normalize())
            .collect();
        let truth = PoseTruth {
            g_m_s2,
            vertical_rad_s,
        };
        let mut obs = truth.observations(series, segmentation, &poses, &dirs);
        let rate = series.sample_rate_hz();
        let (accel_floor, gyro_floor) = floors(series, &obs, &opts)?;
        let n: Vec<usize> = poses
            .iter()
            .map(|&i| obs.segmentation.segments[i].n)
            .collect();
        let accel_points = floored_points(&obs.points(Triad::Accel), &accel_floor, rate, &n);
        let spectral = [
            spectral_lines(series, &obs, Triad::Accel),
            spectral_lines(series, &obs, Triad::Gyro),
        ];
        let mut wb = Workbench {
            series,
            accel_index: poses.clone(),
            gyro_index: poses.clone(),
            obs: obs.clone(),
            accel_floor,
            gyro_floor,
            accel_points,
            gyro_points: Vec::new(),
            opts,
            spectral,
            mode: Mode::ReferenceFree {
                magnitude: Magnitude {
                    g_m_s2,
                    dirs: dirs.clone(),
                    gravity_m_s2,
                    latitude_deg,
                },
                setup: Box::default(),
                moves: Vec::new(),
                moves_skipped: 0,
            },
            notes: crate::note::Notes(vec![
                gravity_note,
                crate::note::Note::AccelMagnitude,
                crate::note::Note::EarthRateAtPoses { latitude_deg },
                crate::note::Note::GyroMoves,
            ]),
        };
        let (up, accel) = wb.calibrated_up(dirs);
        wb.set_up(&mut obs, &up, &truth);
        let mut gyro_points = floored_points(&obs.points(Triad::Gyro), &wb.gyro_floor, rate, &n);
        add_unknown_earth_rate(&mut gyro_points, &up, latitude_deg);
        wb.gyro_points = gyro_points;
        let conditions = poses_conditions(series, &obs, &poses);
        wb.set_moves(
            &obs,
            MovesSetup {
                poses,
                up,
                conditions,
                g_m_s2,
                accel,
            },
        );
        wb.obs = obs;
        Ok(wb)
    }

    /// The calibrated up direction of each pose, from a bias + scale + misalignment fit of
    /// the magnitudes, and that accel model (the measured directions `dirs` and no correction
    /// if that fit fails).
    fn calibrated_up(&self, dirs: Vec<Vec3>) -> (Vec<Vec3>, TriadModel) {
        let first = TriadModel::with_effects(&TriadModel::PAPER_BASE);
        let mag = self.reference_free_magnitude().expect("set above").clone();
        match self.fit_magnitude(&mag, &first, None) {
            Ok(f) => (
                self.accel_points
                    .iter()
                    .map(|p| f.fit.model.inverse(p.measured, &p.conditions).normalize())
                    .collect(),
                f.fit.model,
            ),
            Err(_) => (dirs, TriadModel::default()),
        }
    }

    /// Sets the true inputs of the poses (in `obs` and the accel points) along the calibrated
    /// `up` directions, and the segments' truth to match.
    fn set_up(&mut self, obs: &mut Observations, up: &[Vec3], truth: &PoseTruth) {
        let (g_m_s2, vertical_rad_s) = (truth.g_m_s2, truth.vertical_rad_s);
        for (k, (_, p)) in obs.accel.iter_mut().enumerate() {
            p.true_input = up[k] * g_m_s2;
            p.conditions.specific_force_m_s2 = up[k] * g_m_s2;
            self.accel_points[k].true_input = p.true_input;
            self.accel_points[k].conditions.specific_force_m_s2 = p.true_input;
        }
        for (k, (i, p)) in obs.gyro.iter_mut().enumerate() {
            p.true_input = up[k] * vertical_rad_s;
            p.conditions.specific_force_m_s2 = up[k] * g_m_s2;
            obs.segment_truth[*i] = crate::calibrate::SegmentTruth {
                specific_force_m_s2: (up[k] * g_m_s2).into(),
                angular_rate_rad_s: p.true_input.into(),
                temp_c: p.conditions.temp_c,
                time_since_power_on_s: p.conditions.time_since_power_on_s,
            };
        }
    }

    /// Prepares the moves between the poses of `setup` (the rate corrected by the poses'
    /// rates only) and keeps the setup for models whose offsets vary along a move.
    fn set_moves(&mut self, obs: &Observations, setup: MovesSetup) {
        let (prepared, skipped) = setup.prepare(self.series, obs, None);
        if let Mode::ReferenceFree {
            moves,
            moves_skipped,
            setup: kept,
            ..
        } = &mut self.mode
        {
            (*moves, *moves_skipped, *kept) = (prepared, skipped, Box::new(setup));
        }
    }
}

/// What the moves between the still poses are prepared from (reference-free).
#[derive(Clone, Debug, Default)]
pub(super) struct MovesSetup {
    /// Segment indices of the still poses, in time order.
    pub(super) poses: Vec<usize>,
    /// Calibrated up direction of each pose.
    pub(super) up: Vec<Vec3>,
    /// Conditions of each pose.
    pub(super) conditions: Vec<imu_model::Conditions>,
    /// Local gravity, m/s^2.
    pub(super) g_m_s2: f64,
    /// The accel model of the up directions: the specific force of each sample along a move.
    pub(super) accel: TriadModel,
}

impl MovesSetup {
    /// The moves and how many were skipped; with `gyro`, its offset effects are applied along
    /// each move ([`crate::calibrate::reference_free::MoveOffsets`]).
    pub(super) fn prepare(
        &self,
        series: &ImuSeries,
        obs: &Observations,
        gyro: Option<&TriadModel>,
    ) -> (Vec<crate::calibrate::reference_free::MoveData>, usize) {
        use crate::calibrate::reference_free::{MoveInputs, MoveOffsets, prepare_moves};
        let pose_segs: Vec<&crate::segment::Segment> = self
            .poses
            .iter()
            .map(|&i| &obs.segmentation.segments[i])
            .collect();
        let inputs = MoveInputs {
            series,
            poses: &pose_segs,
            up: &self.up,
            conditions: &self.conditions,
            g_m_s2: self.g_m_s2,
        };
        let offsets = gyro.map(|gyro| MoveOffsets {
            gyro,
            accel: &self.accel,
        });
        prepare_moves(&inputs, offsets)
    }
}

/// The true rate along up at a still pose: Earth's vertical rate at `latitude_deg`, 0
/// without it (the rest of Earth's rate is counted as noise of each pose mean), rad/s.
fn earth_rate_truth(latitude_deg: Option<f64>) -> f64 {
    latitude_deg.map_or(0.0, |lat| imu_model::earth::earth_rate_split_rad_s(lat).0)
}

/// Adds to each gyro point's standard error the variance of the unknown part of Earth's rate
/// on each axis of a pose whose up direction is `up`: a horizontal vector at a random
/// heading, or, without a latitude, a vector in a random direction.
fn add_unknown_earth_rate(points: &mut [FitPoint], up: &[Vec3], latitude_deg: Option<f64>) {
    let earth_var =
        |u: &Vec3, a: usize| imu_model::earth::unknown_heading_variance_rad2_s2(latitude_deg, u[a]);
    for (p, u) in points.iter_mut().zip(up) {
        for a in 0..3 {
            p.std_error[a] = (p.std_error[a].powi(2) + earth_var(u, a)).sqrt();
        }
    }
}

/// The true inputs at a still pose, along its up direction.
struct PoseTruth {
    /// Local gravity, m/s^2.
    g_m_s2: f64,
    /// Earth's rate along up, rad/s (0 without a latitude).
    vertical_rad_s: f64,
}

impl PoseTruth {
    /// The fit point of pose segment `s` with up direction `up`: its gyro or accel mean
    /// against the true input.
    fn point(
        &self,
        series: &ImuSeries,
        s: &crate::segment::Segment,
        up: &Vec3,
        gyro: bool,
    ) -> FitPoint {
        use crate::calibrate::reference_free::{mean_se, pose_conditions};
        let (g_m_s2, vertical_rad_s) = (self.g_m_s2, self.vertical_rad_s);
        let c = pose_conditions(series, s);
        FitPoint {
            true_input: if gyro {
                up * vertical_rad_s
            } else {
                up * g_m_s2
            },
            measured: if gyro { s.mean_gyro() } else { s.mean_accel() },
            std_error: mean_se(
                if gyro {
                    s.std_gyro_rad_s
                } else {
                    s.std_accel_m_s2
                },
                s.n,
            ),
            conditions: imu_model::Conditions {
                specific_force_m_s2: up * g_m_s2,
                ..c
            },
            t_s: 0.5 * (s.start_s + s.end_s),
            duration_s: s.end_s - s.start_s,
        }
    }

    /// Observations of the still `poses` (segment indices) along their measured directions
    /// `dirs`; the segments' truth is unknown until the up directions are calibrated.
    fn observations(
        &self,
        series: &ImuSeries,
        segmentation: crate::segment::Segmentation,
        poses: &[usize],
        dirs: &[Vec3],
    ) -> Observations {
        let point = |i: usize, up: &Vec3, gyro: bool| {
            self.point(series, &segmentation.segments[i], up, gyro)
        };
        let unknown = crate::calibrate::SegmentTruth {
            specific_force_m_s2: [f64::NAN; 3],
            angular_rate_rad_s: [f64::NAN; 3],
            temp_c: f64::NAN,
            time_since_power_on_s: f64::NAN,
        };
        Observations {
            segment_truth: vec![unknown; segmentation.segments.len()],
            accel: poses
                .iter()
                .zip(dirs)
                .map(|(&i, u)| (i, point(i, u, false)))
                .collect(),
            gyro: poses
                .iter()
                .zip(dirs)
                .map(|(&i, u)| (i, point(i, u, true)))
                .collect(),
            segmentation,
        }
    }
}

/// The recording conditions (temperature, time) of each pose.
fn poses_conditions(
    series: &ImuSeries,
    obs: &Observations,
    poses: &[usize],
) -> Vec<imu_model::Conditions> {
    poses
        .iter()
        .map(|&i| {
            crate::calibrate::reference_free::pose_conditions(series, &obs.segmentation.segments[i])
        })
        .collect()
}
