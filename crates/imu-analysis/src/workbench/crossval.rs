//! Cross-validation of a claim: the candidate the workbench would claim is refitted on training
//! folds of the observations (segments, poses or moves) with and without it, and held against the
//! held-out ones. It is claimed only if it also lowers the error there.
//!
//! The rule ([`HeldOut::confirmed`]): the held-out weighted sum of squares falls with the
//! candidate in a strict majority of the folds and over all folds together. Folds are
//! deterministic: leave one out below [`LOO_BELOW`] observations, else [`K_FOLDS`] folds with
//! observation `i` in fold `i mod k` (interleaved in time, so every fold spans the recording).

use super::*;

/// Below this many observations every one is held out in turn (leave one out).
pub(super) const LOO_BELOW: usize = 10;

/// Number of folds with [`LOO_BELOW`] or more observations.
pub(super) const K_FOLDS: usize = 5;

/// How the observations were split.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FoldScheme {
    /// Every observation held out in turn.
    LeaveOneOut,
    /// `k` folds, observation `i` in fold `i mod k`.
    KFold,
}

/// What a fold holds out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HeldOutUnit {
    /// Segment means against a reference (static positions and rate plateaus).
    Segments,
    /// Still poses (reference-free).
    Poses,
    /// Moves between poses (reference-free gyro gains).
    Moves,
}

impl HeldOutUnit {
    /// The plural noun, for reports.
    pub fn noun(self) -> &'static str {
        match self {
            HeldOutUnit::Segments => "segments",
            HeldOutUnit::Poses => "poses",
            HeldOutUnit::Moves => "moves",
        }
    }
}

/// A candidate held against observations its fit did not see.
#[derive(Clone, Debug, Serialize)]
pub struct HeldOut {
    /// How the observations were split.
    pub scheme: FoldScheme,
    /// Number of folds.
    pub folds: usize,
    /// What was held out.
    pub unit: HeldOutUnit,
    /// Number of observations.
    pub n_observations: usize,
    /// Weighted RMS (weights 1/floor^2) of the full-data fit's residuals per axis, base model,
    /// U (rad for moves).
    pub in_sample_rms_before: [f64; 3],
    /// The same with the candidate.
    pub in_sample_rms_after: [f64; 3],
    /// Weighted RMS of the held-out residuals per axis (every observation held out once), base
    /// model refitted on the other folds, U (rad for moves).
    pub held_out_rms_before: [f64; 3],
    /// The same with the candidate.
    pub held_out_rms_after: [f64; 3],
    /// Folds whose held-out weighted sum of squares fell with the candidate.
    pub folds_improved: usize,
    /// Folds in which a fit failed (counted as not improved).
    pub folds_failed: usize,
    /// Improved in a strict majority of folds and over all folds together.
    pub confirmed: bool,
}

impl HeldOut {
    /// `5-fold over segments` or `leave-one-out over 8 poses`.
    pub fn scheme_text(&self) -> String {
        match self.scheme {
            FoldScheme::KFold => format!("{}-fold over {}", self.folds, self.unit.noun()),
            FoldScheme::LeaveOneOut => format!(
                "leave-one-out over {} {}",
                self.n_observations,
                self.unit.noun()
            ),
        }
    }

    /// The unit of the RMS figures of a check on `triad`: rad for moves, else the triad's.
    pub fn rms_unit(&self, triad: Triad) -> &'static str {
        match self.unit {
            HeldOutUnit::Moves => "rad",
            _ => triad.unit(),
        }
    }

    /// One line: the scheme, held-out RMS before and after next to the in-sample figures
    /// (`unit` from [`HeldOut::rms_unit`]), the folds improved and the verdict.
    pub fn summary(&self, unit: &str) -> String {
        format!(
            "held-out ({}): weighted RMS {} -> {} {unit} (in-sample {} -> {}), lower in {} of {} \
             folds{}: {}",
            self.scheme_text(),
            fmt3(self.held_out_rms_before),
            fmt3(self.held_out_rms_after),
            fmt3(self.in_sample_rms_before),
            fmt3(self.in_sample_rms_after),
            self.folds_improved,
            self.folds,
            if self.folds_failed > 0 {
                format!(" ({} failed to fit)", self.folds_failed)
            } else {
                String::new()
            },
            self.verdict_text()
        )
    }

    /// `confirmed on held-out data` or `not confirmed on held-out data`.
    pub fn verdict_text(&self) -> &'static str {
        if self.confirmed {
            "confirmed on held-out data"
        } else {
            "not confirmed on held-out data"
        }
    }
}

/// Weighted squared residuals of some observations: per axis `sum r^2 / s^2` and `sum 1 / s^2`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct WeightedSums {
    pub(super) ss: [f64; 3],
    pub(super) weight: [f64; 3],
}

impl WeightedSums {
    /// Adds residual `r` with standard deviation `s` per axis.
    pub(super) fn add(&mut self, r: [f64; 3], s: [f64; 3]) {
        for a in 0..3 {
            let w = 1.0 / s[a].max(1e-300).powi(2);
            self.ss[a] += w * r[a] * r[a];
            self.weight[a] += w;
        }
    }

    fn merge(&mut self, o: &WeightedSums) {
        for a in 0..3 {
            self.ss[a] += o.ss[a];
            self.weight[a] += o.weight[a];
        }
    }

    /// Whitened sum of squares over the axes.
    pub(super) fn total(&self) -> f64 {
        self.ss.iter().sum()
    }

    /// Weighted RMS per axis.
    pub(super) fn rms(&self) -> [f64; 3] {
        std::array::from_fn(|a| (self.ss[a] / self.weight[a].max(1e-300)).sqrt())
    }
}

/// Held-out sums of one fold: (base model, with the candidate); None when a fit failed.
pub(super) type FoldSums = Option<(WeightedSums, WeightedSums)>;

/// The deterministic folds of `n` observations: (scheme, test indices per fold).
pub(super) fn folds(n: usize) -> (FoldScheme, Vec<Vec<usize>>) {
    if n < LOO_BELOW {
        (FoldScheme::LeaveOneOut, (0..n).map(|i| vec![i]).collect())
    } else {
        let sets = (0..K_FOLDS)
            .map(|f| (f..n).step_by(K_FOLDS).collect())
            .collect();
        (FoldScheme::KFold, sets)
    }
}

/// The observations of `0..n` not in `test`.
pub(super) fn training(n: usize, test: &[usize]) -> Vec<usize> {
    (0..n).filter(|i| !test.contains(i)).collect()
}

/// Runs `fold(train, test)` over the folds of `n` observations and applies the rule;
/// `in_sample` are the full-data fits' sums (before, after). None with fewer than 3
/// observations (nothing to hold out).
pub(super) fn cross_validate(
    n: usize,
    unit: HeldOutUnit,
    in_sample: (WeightedSums, WeightedSums),
    fold: impl Fn(&[usize], &[usize]) -> FoldSums + Sync,
) -> Option<HeldOut> {
    if n < 3 {
        return None;
    }
    let (scheme, sets) = folds(n);
    let (mut before, mut after) = (WeightedSums::default(), WeightedSums::default());
    let (mut improved, mut failed) = (0, 0);
    // The folds are refitted independently (spread over the cores) and merged in fold order.
    let fitted = parallel_map(&sets, |test| fold(&training(n, test), test));
    for result in fitted {
        match result {
            Some((b, a)) => {
                improved += usize::from(a.total() < b.total());
                before.merge(&b);
                after.merge(&a);
            }
            None => failed += 1,
        }
    }
    let folds = sets.len();
    let confirmed = 2 * improved > folds && after.total() < before.total();
    Some(HeldOut {
        scheme,
        folds,
        unit,
        n_observations: n,
        in_sample_rms_before: in_sample.0.rms(),
        in_sample_rms_after: in_sample.1.rms(),
        held_out_rms_before: before.rms(),
        held_out_rms_after: after.rms(),
        folds_improved: improved,
        folds_failed: failed,
        confirmed,
    })
}

impl<'a> Workbench<'a> {
    /// The workbench restricted to the observations `keep` (indices into the points) of
    /// `triad`, for fitting a training fold. The moves are left out (the still-pose fits do
    /// not use them).
    fn subset(&self, triad: Triad, keep: &[usize]) -> Workbench<'a> {
        fn pick<T: Clone>(v: &[T], keep: &[usize]) -> Vec<T> {
            keep.iter().map(|&i| v[i].clone()).collect()
        }
        let accel = triad == Triad::Accel;
        let sub = |v: &Vec<FitPoint>, mine: bool| if mine { pick(v, keep) } else { v.clone() };
        let sub_index = |v: &Vec<usize>, mine: bool| if mine { pick(v, keep) } else { v.clone() };
        let mode = match &self.mode {
            Mode::Reference => Mode::Reference,
            Mode::ReferenceFree {
                magnitude, setup, ..
            } => Mode::ReferenceFree {
                magnitude: Magnitude {
                    dirs: if accel {
                        pick(&magnitude.dirs, keep)
                    } else {
                        magnitude.dirs.clone()
                    },
                    ..magnitude.clone()
                },
                setup: setup.clone(),
                moves: Vec::new(),
                moves_skipped: 0,
            },
        };
        Workbench {
            series: self.series,
            obs: self.obs.clone(),
            accel_floor: self.accel_floor.clone(),
            gyro_floor: self.gyro_floor.clone(),
            accel_points: sub(&self.accel_points, accel),
            gyro_points: sub(&self.gyro_points, !accel),
            accel_index: sub_index(&self.accel_index, accel),
            gyro_index: sub_index(&self.gyro_index, !accel),
            opts: self.opts.clone(),
            spectral: self.spectral.clone(),
            mode,
            notes: crate::note::Notes::default(),
        }
    }

    /// Weighted sums of the residuals of model `m` at the observations `which` of `triad`
    /// (segment means: `m(true input) - measured`; gravity magnitudes: `g - |m^-1(mean)|`
    /// along the pose's direction, weighted by the floor projected on it).
    pub(super) fn sums(&self, triad: Triad, m: &TriadModel, which: &[usize]) -> WeightedSums {
        let (points, _, _) = self.points(triad);
        let mut s = WeightedSums::default();
        for &k in which {
            let p = &points[k];
            match self.magnitude(triad) {
                Some(mag) => {
                    let u = mag.dirs[k];
                    let e = mag.g_m_s2 - m.inverse(p.measured, &p.conditions).norm();
                    let sd = (0..3)
                        .map(|a| (u[a] * p.std_error[a]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    s.add(std::array::from_fn(|a| e * u[a]), [sd; 3]);
                }
                None => {
                    let r = m.forward(p.true_input, &p.conditions) - p.measured;
                    s.add(r.into(), p.std_error.into());
                }
            }
        }
        s
    }

    /// The candidate `cand` (fitted model `cand_model`) held against held-out observations:
    /// the base model `c.profiled` and the candidate refitted on each training fold (the wander
    /// family of the base fit), their residuals at the held-out observations.
    pub(super) fn held_out(&self, c: &CandidateBase, cand_model: &TriadModel) -> Option<HeldOut> {
        let triad = c.triad;
        let n = c.points.len();
        let all: Vec<usize> = (0..n).collect();
        let base_model = &c.profiled.fit.model;
        let in_sample = (
            self.sums(triad, base_model, &all),
            self.sums(triad, cand_model, &all),
        );
        let unit = if self.reference_free_magnitude().is_some() {
            HeldOutUnit::Poses
        } else {
            HeldOutUnit::Segments
        };
        cross_validate(n, unit, in_sample, |train, test| {
            let sub = self.subset(triad, train);
            let m0 = sub.fit(triad, base_model, Some(c.family)).ok()?.fit.model;
            let m1 = sub.fit(triad, cand_model, Some(c.family)).ok()?.fit.model;
            Some((self.sums(triad, &m0, test), self.sums(triad, &m1, test)))
        })
    }

    /// The claimed candidate among `candidates` (at most one) held against held-out
    /// observations: its [`HeldOut`] is recorded, and the claim withdrawn unless confirmed.
    pub(super) fn confirm_claim(&self, c: &CandidateBase, candidates: &mut [Candidate]) {
        for cand in candidates.iter_mut().filter(|x| x.claimed) {
            let Some(model) = cand.model.clone() else {
                continue;
            };
            cand.held_out = self.held_out(c, &model);
            cand.claimed = cand.held_out.as_ref().is_some_and(|h| h.confirmed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folds_are_deterministic_and_cover_every_observation_once() {
        let (scheme, sets) = folds(4);
        assert_eq!(scheme, FoldScheme::LeaveOneOut);
        assert_eq!(sets, vec![vec![0], vec![1], vec![2], vec![3]]);
        let (scheme, sets) = folds(12);
        assert_eq!(scheme, FoldScheme::KFold);
        assert_eq!(sets.len(), K_FOLDS);
        assert_eq!(sets[0], vec![0, 5, 10]);
        assert_eq!(sets[4], vec![4, 9]);
        let mut all: Vec<usize> = sets.concat();
        all.sort_unstable();
        assert_eq!(all, (0..12).collect::<Vec<_>>());
        assert_eq!(training(5, &[1, 3]), vec![0, 2, 4]);
    }

    /// Sums whose whitened total is `t` (on x, weight 1).
    fn sums(t: f64) -> WeightedSums {
        let mut s = WeightedSums::default();
        s.add([t.sqrt(), 0.0, 0.0], [1.0; 3]);
        s
    }

    #[test]
    fn the_rule_needs_a_majority_of_folds_and_the_total() {
        let base = (sums(1.0), sums(1.0));
        // Lower in 3 of 5 folds and overall: confirmed.
        let h = cross_validate(12, HeldOutUnit::Segments, base, |_, test| {
            let after = if test[0] < 3 { 0.5 } else { 1.2 };
            Some((sums(1.0), sums(after)))
        })
        .unwrap();
        assert_eq!((h.folds_improved, h.confirmed), (3, true));
        assert!(h.held_out_rms_after[0] < h.held_out_rms_before[0]);
        // Lower in 3 of 5 folds but higher overall: not confirmed.
        let h = cross_validate(12, HeldOutUnit::Segments, base, |_, test| {
            let after = if test[0] < 3 { 0.9 } else { 2.0 };
            Some((sums(1.0), sums(after)))
        })
        .unwrap();
        assert_eq!((h.folds_improved, h.confirmed), (3, false));
        // Much lower in 2 of 5, failed in the rest: not confirmed (no majority).
        let h = cross_validate(12, HeldOutUnit::Segments, base, |_, test| {
            (test[0] < 2).then(|| (sums(1.0), sums(0.1)))
        })
        .unwrap();
        assert_eq!(
            (h.folds_improved, h.folds_failed, h.confirmed),
            (2, 3, false)
        );
        // Too few observations to hold any out.
        assert!(cross_validate(2, HeldOutUnit::Poses, base, |_, _| None).is_none());
    }
}
