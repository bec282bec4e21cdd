//! The moves between poses: rate integrated to a rotation (quaternions), its noise, and the gyro
//! gains fitted to the rotations.

use super::*;

/// One move prepared for integration.
#[derive(Clone, Debug)]
pub(crate) struct MoveData {
    pub(super) from_pose: usize,
    pub(super) to_pose: usize,
    /// Gyro sample minus the interpolated still-pose rate, rad/s, from the last sample of the
    /// pose before to the first of the pose after.
    pub(super) rate_rad_s: Vec<Vec3>,
    /// Sample interval from the line fitted to the times, s.
    pub(super) step_s: f64,
    /// Calibrated up direction at the pose before.
    pub(super) up_before: Vec3,
    /// Orthonormal basis of the plane normal to the calibrated up direction after.
    pub(super) e1: Vec3,
    pub(super) e2: Vec3,
    /// Conditions for the gain model (those of the pose before).
    pub(super) conditions: Conditions,
    /// Expected noise of each residual component, rad.
    pub(crate) sigma_rad: f64,
}

impl MoveData {
    /// The rotation `sensor_before_from_sensor_after` integrated with the rate corrected by
    /// `gains` (midpoint rule on consecutive samples).
    pub(super) fn rotation(&self, gains: &TriadModel) -> UnitQuaternion<f64> {
        // The whole move corrected at once (its conditions are those of the pose before):
        // the same values as sample by sample, the model's per-call preparation made once.
        let mut w = self.rate_rad_s.clone();
        gains.inverse_batch(&mut w, &self.conditions);
        self.integrate(&w)
    }

    /// The rotation integrated from the corrected rate `w` (one value per sample).
    fn integrate(&self, w: &[Vec3]) -> UnitQuaternion<f64> {
        let mut q = UnitQuaternion::identity();
        for pair in w.windows(2) {
            q *= UnitQuaternion::from_scaled_axis((pair[0] + pair[1]) * (0.5 * self.step_s));
        }
        q
    }

    /// Predicted minus measured up direction after the move, in the plane normal to the
    /// measured one, rad.
    pub(crate) fn residual(&self, gains: &TriadModel) -> [f64; 2] {
        self.residual_of(self.rotation(gains))
    }

    /// [`MoveData::residual`] of the integrated rotation `q`.
    fn residual_of(&self, q: UnitQuaternion<f64>) -> [f64; 2] {
        let predicted = q.inverse_transform_vector(&self.up_before);
        [self.e1.dot(&predicted), self.e2.dot(&predicted)]
    }
}

/// Fewest moves worth a thread of their own in [`move_residuals`] (a move is a few hundred
/// samples integrated: tens of microseconds, against a thread's start of about as much).
const MIN_MOVES_PER_THREAD: usize = 8;

/// [`MoveData::residual`] of every move under `gains`, in order. The moves are integrated on
/// the available cores: each move's integration is independent of the others, so the values
/// are bit-for-bit those of a sequential loop. The gain fits evaluate this for every
/// parameter step and Jacobian column, where nearly all of the workbench's time goes.
pub(crate) fn move_residuals(moves: &[MoveData], gains: &TriadModel) -> Vec<[f64; 2]> {
    on_cores(moves, |_, m| m.residual(gains))
}

/// `f(k, move k)` for every move, in order, the moves split over the available cores.
fn on_cores<T: Send>(moves: &[MoveData], f: impl Fn(usize, &MoveData) -> T + Sync) -> Vec<T> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = cores.min(moves.len() / MIN_MOVES_PER_THREAD).max(1);
    let f = &f;
    let part = move |start: usize, part: &[MoveData]| -> Vec<T> {
        part.iter()
            .enumerate()
            .map(|(i, m)| f(start + i, m))
            .collect()
    };
    if threads == 1 {
        return part(0, moves);
    }
    let chunk = moves.len().div_ceil(threads);
    std::thread::scope(|s| {
        let rest: Vec<_> = moves[chunk..]
            .chunks(chunk)
            .enumerate()
            .map(|(c, p)| s.spawn(move || part(chunk * (c + 1), p)))
            .collect();
        let mut out = part(0, &moves[..chunk]);
        for h in rest {
            out.extend(h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)));
        }
        out
    })
}

/// The first stage of a gain model's inverse (its last effect in canonical order, the first
/// undone) applied to every move's rate, with the bits of that stage's parameters: while a
/// gain fit changes only the other stages' parameters (most Jacobian columns), it is reused.
/// The cubic nonlinearity's inverse, an iteration per value, is the costly first stage.
pub(crate) struct FirstStage {
    key: Vec<u64>,
    rates: Vec<Vec<Vec3>>,
}

/// [`move_residuals`] with the first inverse stage taken from `cache` when its parameters
/// have not changed (else computed and kept): bit-for-bit the same residuals, as the stages
/// are applied to each value in the same order either way.
pub(crate) fn move_residuals_cached(
    moves: &[MoveData],
    gains: &TriadModel,
    cache: &mut Option<FirstStage>,
) -> Vec<[f64; 2]> {
    let stages: Vec<&dyn imu_model::Effect> =
        gains.effect_slots().into_iter().rev().flatten().collect();
    let Some((head, rest)) = stages.split_first() else {
        return move_residuals(moves, gains);
    };
    let mut key: Vec<u64> = head.params().iter().map(|v| v.to_bits()).collect();
    key.push(head.kind() as u64);
    if cache.as_ref().is_none_or(|c| c.key != key) {
        let rates = on_cores(moves, |_, m| {
            let mut w = m.rate_rad_s.clone();
            head.inverse_batch(&mut w, &m.conditions);
            w
        });
        *cache = Some(FirstStage { key, rates });
    }
    let Some(first) = cache.as_ref() else {
        return move_residuals(moves, gains);
    };
    on_cores(moves, |k, m| {
        let mut w = first.rates[k].clone();
        for e in rest {
            e.inverse_batch(&mut w, &m.conditions);
        }
        m.residual_of(m.integrate(&w))
    })
}

/// Two unit vectors completing `u` to an orthonormal basis.
pub(super) fn normal_basis(u: Vec3) -> (Vec3, Vec3) {
    let helper = if u.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let e1 = u.cross(&helper).normalize();
    (e1, u.cross(&e1))
}

/// The gyro gain model `gains` fitted to the integrated rotations of `moves` (two whitened
/// residuals per move), with the parameters marked in `fixed` held.
pub(crate) fn fit_gains(
    moves: &[MoveData],
    gains: &TriadModel,
    fixed: &[bool],
    lsq: &LsqOptions,
) -> Result<LsqSolution, LsqError> {
    let mut work = gains.clone();
    let mut first = None;
    let residual = |p: &[f64]| {
        work.set_params(p);
        let mut r = DVector::zeros(2 * moves.len());
        let res = move_residuals_cached(moves, &work, &mut first);
        for (k, (m, [a, b])) in moves.iter().zip(res).enumerate() {
            r[2 * k] = a / m.sigma_rad;
            r[2 * k + 1] = b / m.sigma_rad;
        }
        r
    };
    let names = gains.param_names(Triad::Gyro);
    least_squares(residual, &gains.params(), fixed, &names, lsq)
}

/// What the moves are prepared from: the recording, its still poses in time order with their
/// calibrated up directions and conditions, and local gravity.
pub(crate) struct MoveInputs<'p> {
    pub(crate) series: &'p ImuSeries,
    pub(crate) poses: &'p [&'p Segment],
    pub(crate) up: &'p [Vec3],
    pub(crate) conditions: &'p [Conditions],
    pub(crate) g_m_s2: f64,
}

/// The offset effects of `model` that vary along a move (all but a constant bias): those the
/// rate measured at the poses around a move cannot carry across it.
pub(crate) fn varying_offsets(model: &TriadModel) -> Vec<EffectKind> {
    model
        .kinds()
        .into_iter()
        .filter(|k| !k.is_gain() && *k != EffectKind::Bias)
        .collect()
}

/// The offset effects of a gyro model, evaluated at every sample of a move: what the rate
/// measured at the two poses around a move cannot carry across it (a g-sensitivity follows the
/// specific force as the unit turns, a temperature bias the temperature, a warm-up the time).
#[derive(Clone, Copy)]
pub(crate) struct MoveOffsets<'m> {
    /// The gyro model whose offset effects (bias, g-sensitivity, temperature bias, warm-up)
    /// are applied; its gains do not enter.
    pub(crate) gyro: &'m TriadModel,
    /// The accel model whose inverse turns each accel sample into the specific force.
    pub(crate) accel: &'m TriadModel,
}

impl MoveOffsets<'_> {
    /// Whether the offsets vary along a move (anything but a constant bias).
    fn vary(&self) -> bool {
        !varying_offsets(self.gyro).is_empty()
    }

    /// How the offsets enter the moves, for the notes (None when they do not vary).
    pub(crate) fn note(&self) -> Option<crate::note::Note> {
        let effects = varying_offsets(self.gyro);
        (!effects.is_empty()).then_some(crate::note::Note::MoveOffsetsVary { effects })
    }

    /// The gyro offset at conditions `c`, rad/s: the model applied to a zero rate (the gains,
    /// applied first in the canonical order, leave a zero rate zero).
    fn at(&self, c: &Conditions) -> Vec3 {
        self.gyro.forward(Vec3::zeros(), c)
    }
}

/// Prepares the moves between consecutive poses; returns them and the number skipped. The rate
/// along each move is corrected by the rate measured at the two poses around it, interpolated
/// in time (bias drift, Earth's rate); with `offsets` whose effects vary along the move, also
/// by their part that the interpolation misses (the offsets at each sample's specific force,
/// temperature and time, less their interpolation between the poses).
pub(crate) fn prepare_moves(
    inputs: &MoveInputs<'_>,
    offsets: Option<MoveOffsets<'_>>,
) -> (Vec<MoveData>, usize) {
    let offsets = offsets.filter(MoveOffsets::vary);
    let mut out = Vec::new();
    let mut skipped = 0;
    for k in 0..inputs.poses.len().saturating_sub(1) {
        match prepare_move(inputs, k, offsets) {
            Some(m) => out.push(m),
            None => skipped += 1,
        }
    }
    (out, skipped)
}

/// The move from pose `k` to pose `k + 1`; None when samples were lost over it.
fn prepare_move(
    inputs: &MoveInputs<'_>,
    k: usize,
    offsets: Option<MoveOffsets<'_>>,
) -> Option<MoveData> {
    let (series, up, conditions) = (inputs.series, inputs.up, inputs.conditions);
    let (a, b) = (inputs.poses[k], inputs.poses[k + 1]);
    let lo = a.first_sample;
    let hi = b.first_sample + b.n - 1;
    let (i0, i1) = (a.first_sample + a.n - 1, b.first_sample);
    if i1 <= i0 || hi <= lo {
        return None;
    }
    let t = &series.t_s[lo..=hi];
    let nominal_s = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    if t.windows(2)
        .any(|w| !(w[1] - w[0] > 0.0 && w[1] - w[0] < 1.5 * nominal_s))
    {
        // Lost samples: the rate over the gap is unknown.
        return None;
    }
    let (x_mean, t_mean, period_s) = time_line(t);
    let time = |i: usize| t_mean + period_s * ((i - lo) as f64 - x_mean);
    let mid_a = time(a.first_sample) + 0.5 * period_s * (a.n - 1) as f64;
    let mid_b = time(b.first_sample) + 0.5 * period_s * (b.n - 1) as f64;
    let (ga, gb) = (a.mean_gyro(), b.mean_gyro());
    let weight_b = |t_s: f64| (t_s - mid_a) / (mid_b - mid_a);
    let pose_offsets = offsets.map(|o| {
        let at_pose = |j: usize| Conditions {
            specific_force_m_s2: up[j] * inputs.g_m_s2,
            ..conditions[j]
        };
        (o, o.at(&at_pose(k)), o.at(&at_pose(k + 1)))
    });
    let rate_rad_s: Vec<Vec3> = (i0..=i1)
        .map(|i| {
            let w = weight_b(time(i));
            let mut r = Vec3::from(series.gyro_rad_s[i]) - (ga * (1.0 - w) + gb * w);
            if let Some((o, oa, ob)) = &pose_offsets {
                r -= o.at(&sample_conditions(series, i, o.accel)) - (oa * (1.0 - w) + ob * w);
            }
            r
        })
        .collect();
    let duration_s = period_s * (i1 - i0) as f64;
    // Integrals of the interpolation weights over the move, for the bias error.
    let (mut int_a, mut int_b) = (0.0, 0.0);
    for i in i0..i1 {
        let w = 0.5 * (weight_b(time(i)) + weight_b(time(i + 1)));
        int_a += (1.0 - w) * period_s;
        int_b += w * period_s;
    }
    let var_rad2 = move_variance_rad2(a, b, period_s, duration_s, [int_a, int_b], inputs.g_m_s2);
    let (e1, e2) = normal_basis(up[k + 1]);
    Some(MoveData {
        from_pose: k,
        to_pose: k + 1,
        rate_rad_s,
        step_s: period_s,
        up_before: up[k],
        e1,
        e2,
        conditions: conditions[k],
        sigma_rad: var_rad2.sqrt().max(1e-12),
    })
}

/// The conditions at sample `i`: the specific force of its accel sample through the `accel`
/// model, the temperature then, and the recording time for the time since power-on (as for
/// the poses).
fn sample_conditions(series: &ImuSeries, i: usize, accel: &TriadModel) -> Conditions {
    let t_s = series.t_s[i];
    let temp_c = series.temp_at(t_s);
    let temp_c = if temp_c.is_finite() {
        temp_c
    } else {
        imu_model::units::REFERENCE_TEMP_C
    };
    let raw = Conditions {
        temp_c,
        time_since_power_on_s: t_s,
        ..Conditions::default()
    };
    Conditions {
        specific_force_m_s2: accel.inverse(Vec3::from(series.accel_m_s2[i]), &raw),
        ..raw
    }
}

/// Straight line of time `t` against sample index: (mean index, mean time, sample period s).
fn time_line(t: &[f64]) -> (f64, f64, f64) {
    let n = t.len() as f64;
    let x_mean = (n - 1.0) / 2.0;
    let t_mean = t.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, ti) in t.iter().enumerate() {
        let dx = i as f64 - x_mean;
        sxy += dx * (ti - t_mean);
        sxx += dx * dx;
    }
    (x_mean, t_mean, sxy / sxx)
}

/// The variance of a move's integrated rotation from pose `a` to pose `b` (rad^2), per axis
/// averaged over the axes: white gyro noise integrated over the move, the error of the two pose
/// rates weighted by their share of the interpolation (`[int_a, int_b]`, the integrals of the
/// interpolation weights, s), and the error of the two gravity directions.
fn move_variance_rad2(
    a: &Segment,
    b: &Segment,
    period_s: f64,
    duration_s: f64,
    [int_a, int_b]: [f64; 2],
    g_m_s2: f64,
) -> f64 {
    let mean_sq = |v: Vec3| v.norm_squared() / 3.0;
    let white_var =
        (mean_sq(Vec3::from(a.std_gyro_rad_s)) + mean_sq(Vec3::from(b.std_gyro_rad_s))) / 2.0;
    white_var * period_s * duration_s
        + int_a * int_a * mean_sq(mean_se(a.std_gyro_rad_s, a.n))
        + int_b * int_b * mean_sq(mean_se(b.std_gyro_rad_s, b.n))
        + (mean_sq(mean_se(a.std_accel_m_s2, a.n)) + mean_sq(mean_se(b.std_accel_m_s2, b.n)))
            / (g_m_s2 * g_m_s2)
}
