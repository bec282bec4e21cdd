//! Allan-family deviations of rate ("fractional frequency") data: ADEV, OADEV, MDEV, HDEV,
//! OHDEV, TDEV, TOTDEV (NIST SP 1065 definitions), tau sets, EDF-based confidence intervals and a
//! bounded-memory streaming OADEV for multi-day recordings.
//!
//! Input is a rate series `y` (e.g. gyro rad/s or accel m/s^2) sampled every `tau0_s`. It is
//! integrated once into the phase `x[0] = 0, x[i+1] = tau0 * sum(y[0..=i])` (the same order of
//! operations as allantools, so results agree to rounding), and every deviation is then an O(N)
//! pass over `x` (MDEV/TDEV use the cumulative sum of `x`, so their inner m-term sums are O(1)).
//! The deviation comes out in the unit of `y`. OADEV, the usual IMU choice, sums all its taus in
//! one cache-blocked pass whose kernels pick the CPU's widest SIMD at run time (AVX2 with FMA on
//! x86-64 v3 and later, through the `pulp` crate, whose dispatch keeps this crate free of
//! `unsafe`); the build itself stays baseline x86-64.
//!
//! Confidence intervals: the equivalent degrees of freedom (EDF) of the overlapping Allan
//! variance follow the closed-form approximations in NIST SP 1065 Table 5 (Howe, Allan, Barnes),
//! one per power-law noise type, selected per tau from the local ADEV slope unless a type is
//! given. Other deviations use a conservative EDF equal to the number of non-overlapping
//! difference terms. The chi-squared quantiles use the Wilson-Hilferty cube-root normal
//! approximation, `chi2_p(nu) ~ nu (1 - 2/(9 nu) + z_p sqrt(2/(9 nu)))^3`, with `z_p` from the
//! Abramowitz-Stegun 26.2.23 rational approximation (|error| < 4.5e-4 in z); together they are
//! within about 1% of the exact quantile for nu >= 2, amply good for error bars.

use std::sync::atomic::{AtomicUsize, Ordering};

use pulp::{Arch, Simd, WithSimd};
use serde::Serialize;
use thiserror::Error;

/// Errors of the Allan-deviation computations.
#[derive(Debug, Error, PartialEq)]
pub enum AllanError {
    /// Fewer samples than the smallest averaging factor needs.
    #[error("too few samples: {n_samples} rate samples, need at least {needed}")]
    TooShort {
        /// Rate samples given.
        n_samples: usize,
        /// Rate samples needed.
        needed: usize,
    },
    /// The sample period is not a positive finite number.
    #[error("invalid sample period {tau0_s} s: must be positive and finite")]
    BadPeriod {
        /// The offending period, seconds.
        tau0_s: f64,
    },
}

/// Which deviation to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Non-overlapping Allan deviation.
    Adev,
    /// Overlapping Allan deviation (the usual choice for IMU noise).
    Oadev,
    /// Modified Allan deviation.
    Mdev,
    /// Non-overlapping Hadamard deviation.
    Hdev,
    /// Overlapping Hadamard deviation.
    Ohdev,
    /// Time deviation, tau * MDEV / sqrt(3) (unit of y times seconds).
    Tdev,
    /// Total deviation (reflected-phase extension, NIST SP 1065 eq. 25).
    Totdev,
}

impl Kind {
    /// Every kind, in the order of the NIST reference tables.
    pub const ALL: [Kind; 7] = [
        Kind::Adev,
        Kind::Oadev,
        Kind::Mdev,
        Kind::Totdev,
        Kind::Hdev,
        Kind::Ohdev,
        Kind::Tdev,
    ];

    /// Largest averaging factor m for `n_phase` phase points.
    pub fn max_m(self, n_phase: usize) -> usize {
        let n = n_phase.saturating_sub(1);
        match self {
            Kind::Adev | Kind::Oadev | Kind::Totdev => n / 2,
            Kind::Mdev | Kind::Tdev | Kind::Hdev | Kind::Ohdev => n / 3,
        }
    }
}

/// Power-law noise type (of the rate data y), used to pick an EDF formula.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseType {
    /// White phase modulation (ADEV slope -1; in an IMU: quantization).
    WhitePm,
    /// Flicker phase modulation (ADEV slope -1, log-corrected).
    FlickerPm,
    /// White frequency modulation (slope -1/2; IMU angle/velocity random walk N).
    WhiteFm,
    /// Flicker frequency modulation (slope 0; IMU bias instability B).
    FlickerFm,
    /// Random-walk frequency modulation (slope +1/2; IMU rate random walk K).
    RandomWalkFm,
}

impl NoiseType {
    /// The noise type whose ADEV log-log slope is nearest to `slope`.
    pub fn from_adev_slope(slope: f64) -> Self {
        if !slope.is_finite() || slope < -0.75 {
            NoiseType::WhitePm
        } else if slope < -0.25 {
            NoiseType::WhiteFm
        } else if slope < 0.25 {
            NoiseType::FlickerFm
        } else {
            NoiseType::RandomWalkFm
        }
    }
}

/// Which averaging factors m (tau = m tau0) to evaluate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum TauSet {
    /// m = 1, 2, 4, 8, ... up to the kind's limit.
    Octave,
    /// `n` log-spaced m per decade (rounded, duplicates removed), starting at m = 1.
    PerDecade(u32),
    /// m = 1, 2, 3, ... every factor (slow for long series; for short ones and tests).
    All,
}

impl TauSet {
    /// The averaging factors for a series of `n_phase` phase points and the given maximum m.
    pub fn factors(self, max_m: usize) -> Vec<usize> {
        let mut out = Vec::new();
        match self {
            TauSet::Octave => {
                let mut m = 1usize;
                while m <= max_m {
                    out.push(m);
                    m = m.saturating_mul(2);
                }
            }
            TauSet::PerDecade(n) => {
                let n = f64::from(n.max(1));
                let mut k = 0u32;
                loop {
                    let m = 10f64.powf(f64::from(k) / n).round() as usize;
                    if m > max_m {
                        break;
                    }
                    if out.last() != Some(&m) {
                        out.push(m);
                    }
                    k += 1;
                }
            }
            TauSet::All => out.extend(1..=max_m),
        }
        out
    }
}

impl std::str::FromStr for TauSet {
    type Err = String;

    /// Parses `octave`, `all` or `N-per-decade` (e.g. `10-per-decade`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "octave" => Ok(TauSet::Octave),
            "all" => Ok(TauSet::All),
            _ => s
                .strip_suffix("-per-decade")
                .and_then(|n| n.parse::<u32>().ok())
                .filter(|&n| n > 0)
                .map(TauSet::PerDecade)
                .ok_or_else(|| format!("bad tau set {s:?}: use octave, all or N-per-decade")),
        }
    }
}

/// One deviation value with its statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DevPoint {
    /// Averaging factor (tau = m tau0).
    pub m: usize,
    /// Averaging time, seconds.
    pub tau_s: f64,
    /// The deviation, in the unit of y (TDEV: unit of y times seconds).
    pub dev: f64,
    /// Number of difference terms averaged.
    pub n_terms: usize,
    /// Equivalent degrees of freedom of the variance estimate.
    pub edf: f64,
    /// Lower bound of the confidence interval on `dev`.
    pub dev_lo: f64,
    /// Upper bound of the confidence interval on `dev`.
    pub dev_hi: f64,
}

/// A deviation curve.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DevCurve {
    /// Which deviation.
    pub kind: Kind,
    /// Sample period of the rate data, seconds.
    pub tau0_s: f64,
    /// Confidence level of `dev_lo`..`dev_hi` (e.g. 0.683).
    pub confidence: f64,
    /// Points in increasing tau.
    pub points: Vec<DevPoint>,
}

/// Options of [`deviation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Averaging factors.
    pub taus: TauSet,
    /// Two-sided confidence level of the intervals (default 0.683, "1 sigma").
    pub confidence: f64,
    /// Noise type for the EDF; `None` picks it per tau from the local OADEV slope.
    pub noise: Option<NoiseType>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            taus: TauSet::Octave,
            confidence: 0.683,
            noise: None,
        }
    }
}

/// Series at least this long (phase points) are computed on two threads.
const PARALLEL_MIN_PHASE_POINTS: usize = 1 << 20;

/// Integrates rate data into phase: `x[0] = 0`, `x[i+1] = tau0 * (y[0] + ... + y[i])`.
pub fn phase_from_rate(y: &[f64], tau0_s: f64) -> Vec<f64> {
    let mut x = vec![0.0; y.len() + 1];
    integrate_into(y, tau0_s, &mut x);
    x
}

/// [`phase_from_rate`] into `x` (`y.len() + 1` long; `x[0]` is set to 0).
fn integrate_into(y: &[f64], tau0_s: f64, x: &mut [f64]) {
    x[0] = 0.0;
    // A running sum is one long dependency chain: for long series scan the two halves on two
    // threads, the second starting from the first half's total. That total is summed in the
    // same order as the serial scan would have, so the result is bit-identical to it.
    let scan = |out: &mut [f64], ys: &[f64], start: f64| {
        let mut sum = start;
        for (o, &v) in out.iter_mut().zip(ys) {
            sum += v;
            *o = sum * tau0_s;
        }
    };
    if y.len() < PARALLEL_MIN_PHASE_POINTS {
        scan(&mut x[1..], y, 0.0);
        return;
    }
    let mid = y.len() / 2;
    let (first, second) = x[1..].split_at_mut(mid);
    std::thread::scope(|scope| {
        scope.spawn(|| scan(first, &y[..mid], 0.0));
        let offset: f64 = y[..mid].iter().sum();
        scan(second, &y[mid..], offset);
    });
}

/// Scratch `f64` array for the phase of a series. Long ones (the two-thread sizes) live in
/// anonymous memory with a transparent-huge-page hint: a fresh 80 MB array costs some 20 000
/// page faults at 4 KiB, which took about as long as all the OADEV arithmetic, and some 40 at
/// 2 MiB. Where the kernel gives no huge pages it is ordinary memory; if mapping fails, a `Vec`.
enum LongArray {
    Heap(Vec<f64>),
    Mapped(memmap2::MmapMut),
}

impl LongArray {
    /// `len` zeros.
    fn zeros(len: usize) -> Self {
        if len >= PARALLEL_MIN_PHASE_POINTS
            && let Ok(map) = memmap2::MmapMut::map_anon(len * size_of::<f64>())
        {
            // Only a hint: an error (no THP in this kernel) leaves ordinary pages.
            #[cfg(target_os = "linux")]
            let _ = map.advise(memmap2::Advice::HugePage);
            return LongArray::Mapped(map);
        }
        LongArray::Heap(vec![0.0; len])
    }
}

impl std::ops::Deref for LongArray {
    type Target = [f64];

    fn deref(&self) -> &[f64] {
        match self {
            LongArray::Heap(v) => v,
            // A mapping is page-aligned and its length a multiple of 8, so the cast holds.
            LongArray::Mapped(m) => bytemuck::cast_slice(m),
        }
    }
}

impl std::ops::DerefMut for LongArray {
    fn deref_mut(&mut self) -> &mut [f64] {
        match self {
            LongArray::Heap(v) => v,
            LongArray::Mapped(m) => bytemuck::cast_slice_mut(m),
        }
    }
}

/// Sum of `f(i)` for `i` in `idx`, with four interleaved accumulators (faster, and a little more
/// accurate than one running sum).
#[inline]
fn sum_by(idx: impl Iterator<Item = usize>, f: impl Fn(usize) -> f64) -> f64 {
    let mut acc = [0.0f64; 4];
    for (k, i) in idx.enumerate() {
        acc[k & 3] += f(i);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Sum over all i of (x[i+2m] - 2 x[i+m] + x[i])^2: the overlapping Allan hot loop.
fn second_difference_sum_sq(x: &[f64], m: usize) -> f64 {
    oadev_sums(x, &[m])[0]
}

/// Taus per pass of the second-difference kernels: a block of `x` is read once for up to this
/// many taus, and `UNROLL` x `GROUP` accumulators still fit the 16 vector registers of AVX2.
const GROUP: usize = 4;

/// Independent SIMD vectors per loop step (so the fused multiply-add latency is hidden).
const UNROLL: usize = 2;

/// Elements of `i` per block of the blocked pass (128 KiB of `x` per stream: the streams of one
/// group of taus stay in the per-core L2 cache while the group uses them).
const BLOCK: usize = 16384;

/// Second-difference sums of an octave run of taus `m, 2m, ..., 2^(G-1) m` over `i` in `lo..hi`
/// (`hi + 2^G m <= x.len()`). With `e_k = x[i + 2^k m] - x[i]` the run's second differences are
/// `e_(k+1) - 2 e_k`, so one vector step loads `G + 2` vectors (not `3 G`) and spends a
/// subtraction and two multiply-adds per tau. Written on `pulp` SIMD vectors so it compiles to
/// AVX2/FMA where the CPU has it (see [`oadev_sums`]); the scalar instance of `S` is the plain
/// code the baseline target vectorizes on its own.
#[inline(always)]
fn octave_run_sums<S: Simd, const G: usize>(
    simd: S,
    x: &[f64],
    m: usize,
    lo: usize,
    hi: usize,
) -> [f64; G] {
    let len = hi - lo;
    let at = |offset: usize| &x[lo + offset..lo + offset + len];
    let (base, _) = S::as_simd_f64s(at(0));
    let n_vec = base.len() / UNROLL * UNROLL;
    let base = &base[..n_vec];
    let first = &S::as_simd_f64s(at(m)).0[..n_vec];
    // further[k] is x at offset 2^(k+1) m.
    let further: [&[S::f64s]; G] =
        std::array::from_fn(|k| &S::as_simd_f64s(at(m << (k + 1))).0[..n_vec]);
    let minus_two = simd.splat_f64s(-2.0);
    let zero = simd.splat_f64s(0.0);
    let mut acc = [[zero; G]; UNROLL];
    for v in (0..n_vec).step_by(UNROLL) {
        for (u, acc) in acc.iter_mut().enumerate() {
            let a = base[v + u];
            let mut e_prev = simd.sub_f64s(first[v + u], a);
            for (k, acc) in acc.iter_mut().enumerate() {
                let e_next = simd.sub_f64s(further[k][v + u], a);
                let d = simd.mul_add_e_f64s(minus_two, e_prev, e_next);
                *acc = simd.mul_add_e_f64s(d, d, *acc);
                e_prev = e_next;
            }
        }
    }
    let done = lo + n_vec * S::F64_LANES;
    std::array::from_fn(|k| {
        let mut v = acc[0][k];
        for a in &acc[1..] {
            v = simd.add_f64s(v, a[k]);
        }
        let mk = m << k;
        simd.reduce_sum_f64s(v)
            + (done..hi)
                .map(|i| {
                    let d = (x[i + 2 * mk] - x[i]) - 2.0 * (x[i + mk] - x[i]);
                    d * d
                })
                .sum::<f64>()
    })
}

/// Second-difference sums of any `G` taus `ms` over `i` in `lo..hi` (`hi + 2 max(ms) <= x.len()`):
/// one pass loads the shared `x[i]` once and `x[i + m]`, `x[i + 2m]` per tau.
#[inline(always)]
fn tau_group_sums<S: Simd, const G: usize>(
    simd: S,
    x: &[f64],
    ms: &[usize],
    lo: usize,
    hi: usize,
) -> [f64; G] {
    let len = hi - lo;
    let at = |offset: usize| S::as_simd_f64s(&x[lo + offset..lo + offset + len]).0;
    let n_vec = at(0).len() / UNROLL * UNROLL;
    let base = &at(0)[..n_vec];
    let mid: [&[S::f64s]; G] = std::array::from_fn(|j| &at(ms[j])[..n_vec]);
    let far: [&[S::f64s]; G] = std::array::from_fn(|j| &at(2 * ms[j])[..n_vec]);
    let minus_two = simd.splat_f64s(-2.0);
    let zero = simd.splat_f64s(0.0);
    let mut acc = [[zero; G]; UNROLL];
    for v in (0..n_vec).step_by(UNROLL) {
        for (u, acc) in acc.iter_mut().enumerate() {
            let a = base[v + u];
            for (j, acc) in acc.iter_mut().enumerate() {
                let d = simd.add_f64s(
                    simd.mul_add_e_f64s(minus_two, mid[j][v + u], far[j][v + u]),
                    a,
                );
                *acc = simd.mul_add_e_f64s(d, d, *acc);
            }
        }
    }
    let done = lo + n_vec * S::F64_LANES;
    std::array::from_fn(|j| {
        let mut v = acc[0][j];
        for a in &acc[1..] {
            v = simd.add_f64s(v, a[j]);
        }
        let m = ms[j];
        simd.reduce_sum_f64s(v)
            + (done..hi)
                .map(|i| {
                    let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                    d * d
                })
                .sum::<f64>()
    })
}

/// A run of consecutive taus `ms[start..start + len]` that one kernel pass handles.
#[derive(Debug, Clone, Copy)]
struct TauGroup {
    start: usize,
    len: usize,
    /// Each tau is twice the previous one (the octave-run kernel applies).
    octave: bool,
}

/// Splits increasing `ms` into octave runs and other groups of at most [`GROUP`] taus.
fn tau_groups(ms: &[usize]) -> Vec<TauGroup> {
    let doubles = |k: usize| k + 1 < ms.len() && ms[k + 1] == 2 * ms[k];
    let mut groups = Vec::new();
    let mut k = 0;
    while k < ms.len() {
        let mut len = 1;
        if doubles(k) {
            while len < GROUP && doubles(k + len - 1) {
                len += 1;
            }
        } else {
            while len < GROUP && k + len < ms.len() && !doubles(k + len) {
                len += 1;
            }
        }
        groups.push(TauGroup {
            start: k,
            len,
            octave: len > 1 && doubles(k),
        });
        k += len;
    }
    groups
}

/// Overlapping second-difference sums for every `m` in `ms` at once, over `i` in `range`, in one
/// blocked pass: a block of `x` and its blocks at offsets m and 2m stay in cache while all taus
/// use them, and with octave taus the offset 2m of one tau is the offset m of the next, so memory
/// is read about once per distinct offset instead of three times per tau.
struct BlockedPass<'a> {
    x: &'a [f64],
    ms: &'a [usize],
    range: std::ops::Range<usize>,
}

impl WithSimd for BlockedPass<'_> {
    type Output = Vec<f64>;

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) -> Vec<f64> {
        let BlockedPass { x, ms, range } = self;
        let groups = tau_groups(ms);
        let mut sums = vec![0.0; ms.len()];
        let mut i0 = range.start;
        while i0 < range.end {
            let i1 = (i0 + BLOCK).min(range.end);
            for g in &groups {
                let (taus, out) = (
                    &ms[g.start..g.start + g.len],
                    &mut sums[g.start..g.start + g.len],
                );
                // All taus of the group have terms up to the largest tau's end; the smaller
                // taus' remaining terms in this block are summed one tau at a time.
                let hi = i1.min(x.len() - 2 * taus[g.len - 1]);
                if hi > i0 {
                    macro_rules! run {
                        ($kernel:ident, $n:literal, $arg:expr) => {
                            $kernel::<S, $n>(simd, x, $arg, i0, hi)
                                .iter()
                                .zip(out.iter_mut())
                                .for_each(|(s, o)| *o += s)
                        };
                    }
                    match (g.octave, g.len) {
                        (true, 2) => run!(octave_run_sums, 2, taus[0]),
                        (true, 3) => run!(octave_run_sums, 3, taus[0]),
                        (true, _) => run!(octave_run_sums, 4, taus[0]),
                        (false, 1) => run!(tau_group_sums, 1, taus),
                        (false, 2) => run!(tau_group_sums, 2, taus),
                        (false, 3) => run!(tau_group_sums, 3, taus),
                        (false, _) => run!(tau_group_sums, 4, taus),
                    }
                }
                for (o, &m) in out.iter_mut().zip(taus) {
                    let (lo, end) = (hi.max(i0), i1.min(x.len() - 2 * m));
                    if end > lo {
                        *o += tau_group_sums::<S, 1>(simd, x, &[m], lo, end)[0];
                    }
                }
            }
            i0 = i1;
        }
        sums
    }
}

/// All OADEV second-difference sums for increasing `ms` (each `m <= (x.len() - 1) / 2`), with
/// the widest SIMD the CPU has (runtime dispatch through `pulp`: AVX2 + FMA on x86-64 v3, the
/// baseline instructions otherwise), on two threads for long series. The threads take chunks of
/// `i` from a shared counter, so a thread that loses its core to another process does not hold
/// the other one up, and both read neighbouring parts of `x`; the chunks' sums are added in
/// chunk order, so the result does not depend on which thread took which chunk.
fn oadev_sums(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let Some(&m_min) = ms.first() else {
        return Vec::new();
    };
    let arch = Arch::new();
    let pass = |range| arch.dispatch(BlockedPass { x, ms, range });
    let end = x.len() - 2 * m_min;
    if x.len() < PARALLEL_MIN_PHASE_POINTS {
        return pass(0..end);
    }
    const CHUNK: usize = 4 * BLOCK;
    let next = AtomicUsize::new(0);
    let work = || {
        let mut done = Vec::new();
        loop {
            let c = next.fetch_add(1, Ordering::Relaxed);
            if c * CHUNK >= end {
                return done;
            }
            done.push((c, pass(c * CHUNK..((c + 1) * CHUNK).min(end))));
        }
    };
    let (mut chunks, theirs) = std::thread::scope(|scope| {
        let other = scope.spawn(work);
        let mine = work();
        (mine, other.join().expect("deviation worker panicked"))
    });
    chunks.extend(theirs);
    chunks.sort_unstable_by_key(|&(c, _)| c);
    let mut sums = vec![0.0; ms.len()];
    for (_, part) in &chunks {
        for (s, p) in sums.iter_mut().zip(part) {
            *s += p;
        }
    }
    sums
}

fn check(n_y: usize, tau0_s: f64) -> Result<(), AllanError> {
    if !(tau0_s.is_finite() && tau0_s > 0.0) {
        return Err(AllanError::BadPeriod { tau0_s });
    }
    if n_y < 2 {
        return Err(AllanError::TooShort {
            n_samples: n_y,
            needed: 2,
        });
    }
    Ok(())
}

/// Variance and number of terms of one deviation at one m, from phase `x` (and `cx`, the
/// cumulative sum of `x` with a leading 0, for MDEV/TDEV). Returns `None` if m is out of range.
fn variance_at(kind: Kind, x: &[f64], cx: &[f64], m: usize, tau0_s: f64) -> Option<(f64, usize)> {
    let n = x.len();
    if m == 0 || m > kind.max_m(n) {
        return None;
    }
    let tau = m as f64 * tau0_s;
    Some(match kind {
        Kind::Oadev | Kind::Adev => {
            let stride = if kind == Kind::Adev { m } else { 1 };
            let last = n - 1 - 2 * m;
            let terms = last / stride + 1;
            let s = if stride == 1 {
                second_difference_sum_sq(x, m)
            } else {
                sum_by((0..=last).step_by(stride), |i| {
                    let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                    d * d
                })
            };
            (s / (2.0 * terms as f64 * tau * tau), terms)
        }
        Kind::Hdev | Kind::Ohdev => {
            let stride = if kind == Kind::Hdev { m } else { 1 };
            let last = n - 1 - 3 * m;
            let terms = last / stride + 1;
            let s = sum_by((0..=last).step_by(stride), |i| {
                let d = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
                d * d
            });
            (s / (6.0 * terms as f64 * tau * tau), terms)
        }
        Kind::Mdev | Kind::Tdev => {
            // sum_{i=j}^{j+m-1} (x[i+2m] - 2x[i+m] + x[i]) from the cumulative sum cx.
            let terms = n - 3 * m + 1;
            let s = sum_by(0..terms, |j| {
                let d = (cx[j + 3 * m] - cx[j + 2 * m]) - 2.0 * (cx[j + 2 * m] - cx[j + m])
                    + (cx[j + m] - cx[j]);
                d * d
            });
            let mvar = s / (2.0 * (m * m) as f64 * tau * tau * terms as f64);
            if kind == Kind::Tdev {
                (mvar * tau * tau / 3.0, terms)
            } else {
                (mvar, terms)
            }
        }
        Kind::Totdev => {
            // Phase reflected about both end points: x*(-j) = 2x(0) - x(j),
            // x*(n-1+j) = 2x(n-1) - x(n-1-j), for j = 1..n-2.
            let xs = |k: isize| -> f64 {
                let last = n as isize - 1;
                if k < 0 {
                    2.0 * x[0] - x[(-k) as usize]
                } else if k > last {
                    2.0 * x[n - 1] - x[(2 * last - k) as usize]
                } else {
                    x[k as usize]
                }
            };
            let mi = m as isize;
            let s = sum_by(1..n - 1, |i| {
                let i = i as isize;
                let d = xs(i - mi) - 2.0 * xs(i) + xs(i + mi);
                d * d
            });
            (s / (2.0 * (n - 2) as f64 * tau * tau), n - 2)
        }
    })
}

/// Equivalent degrees of freedom of the overlapping Allan variance (NIST SP 1065 Table 5) for
/// `n_phase` phase points at averaging factor `m`.
pub fn edf_oadev(n_phase: usize, m: usize, noise: NoiseType) -> f64 {
    let n = n_phase as f64;
    let m = m as f64;
    let edf = match noise {
        NoiseType::WhitePm => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        NoiseType::FlickerPm => {
            let a = ((n - 1.0) / (2.0 * m)).ln();
            let b = ((2.0 * m + 1.0) * (n - 1.0) / 4.0).ln();
            (a * b).max(0.0).sqrt().exp()
        }
        NoiseType::WhiteFm => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0)
        }
        NoiseType::FlickerFm => {
            if m <= 1.0 {
                2.0 * (n - 2.0).powi(2) / (2.3 * n - 4.9)
            } else {
                5.0 * n * n / (4.0 * m * (n + 3.0 * m))
            }
        }
        NoiseType::RandomWalkFm => {
            (n - 2.0) / m * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
                / (n - 3.0).powi(2)
        }
    };
    // No noise gives more degrees of freedom than about 3(N-1)/(2m) at long averaging times
    // (the white-FM limit). The cap matters when the per-tau noise type is picked from a noisy
    // local slope at the longest taus: a spurious slope of -1 would select the white-PM formula,
    // whose EDF stays near N/2, and give the least certain points the greatest weight.
    let cap = 3.0 * (n - 1.0) / (2.0 * m);
    if edf.is_finite() {
        edf.min(cap).max(1.0)
    } else {
        1.0
    }
}

/// Standard normal quantile (Abramowitz & Stegun 26.2.23, |error| < 4.5e-4).
pub fn normal_quantile(p: f64) -> f64 {
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let (q, sign) = if p < 0.5 { (p, -1.0) } else { (1.0 - p, 1.0) };
    let t = (-2.0 * q.ln()).sqrt();
    let z = t
        - (2.515_517 + 0.802_853 * t + 0.010_328 * t * t)
            / (1.0 + 1.432_788 * t + 0.189_269 * t * t + 0.001_308 * t * t * t);
    sign * z
}

/// Chi-squared quantile with `nu` degrees of freedom at probability `p` (Wilson-Hilferty).
pub fn chi2_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let a = 2.0 / (9.0 * nu);
    (nu * (1.0 - a + z * a.sqrt()).powi(3)).max(1e-12 * nu)
}

/// Two-sided confidence interval `(lo, hi)` on a deviation with `edf` degrees of freedom.
pub fn confidence_interval(dev: f64, edf: f64, confidence: f64) -> (f64, f64) {
    let alpha = 1.0 - confidence;
    let lo = dev * (edf / chi2_quantile(1.0 - alpha / 2.0, edf)).sqrt();
    let hi = dev * (edf / chi2_quantile(alpha / 2.0, edf)).sqrt();
    (lo, hi)
}

/// Computes one deviation of rate data `y` (sample period `tau0_s`) at the tau set in `options`.
pub fn deviation(
    kind: Kind,
    y: &[f64],
    tau0_s: f64,
    options: &Options,
) -> Result<DevCurve, AllanError> {
    check(y.len(), tau0_s)?;
    let mut x = LongArray::zeros(y.len() + 1);
    integrate_into(y, tau0_s, &mut x);
    deviation_from_phase(kind, &x, tau0_s, options)
}

/// As [`deviation`], from phase data `x` (integrated rate, unit of y times seconds).
pub fn deviation_from_phase(
    kind: Kind,
    x: &[f64],
    tau0_s: f64,
    options: &Options,
) -> Result<DevCurve, AllanError> {
    check(x.len().saturating_sub(1), tau0_s)?;
    let cx = if matches!(kind, Kind::Mdev | Kind::Tdev) {
        let mut c = Vec::with_capacity(x.len() + 1);
        c.push(0.0);
        let mut s = 0.0;
        for &v in x {
            s += v;
            c.push(s);
        }
        c
    } else {
        Vec::new()
    };
    let n = x.len();
    let factors = options.taus.factors(kind.max_m(n));
    if factors.is_empty() {
        return Err(AllanError::TooShort {
            n_samples: n - 1,
            needed: if matches!(kind, Kind::Adev | Kind::Oadev | Kind::Totdev) {
                2
            } else {
                3
            },
        });
    }
    // OADEV: every tau in one blocked pass (see `oadev_sums`).
    let fused: Vec<(usize, f64)> = if kind == Kind::Oadev {
        let ms: Vec<usize> = factors
            .iter()
            .copied()
            .filter(|&m| m <= kind.max_m(n))
            .collect();
        ms.iter().copied().zip(oadev_sums(x, &ms)).collect()
    } else {
        Vec::new()
    };
    let point = |m: usize| {
        let (var, n_terms) = match fused.iter().find(|(fm, _)| *fm == m) {
            Some(&(_, sum)) => {
                let terms = n - 2 * m;
                let tau = m as f64 * tau0_s;
                (sum / (2.0 * terms as f64 * tau * tau), terms)
            }
            None => variance_at(kind, x, &cx, m, tau0_s)?,
        };
        Some(DevPoint {
            m,
            tau_s: m as f64 * tau0_s,
            dev: var.max(0.0).sqrt(),
            n_terms,
            edf: 0.0,
            dev_lo: 0.0,
            dev_hi: 0.0,
        })
    };
    // Long series: the taus are independent passes over memory; split them over two threads
    // (interleaved, so both get short and long taus). Results do not depend on the split.
    let mut points: Vec<DevPoint> =
        if n >= PARALLEL_MIN_PHASE_POINTS && factors.len() > 1 && kind != Kind::Oadev {
            let (mut a, b) = std::thread::scope(|scope| {
                let other = scope.spawn(|| {
                    factors
                        .iter()
                        .skip(1)
                        .step_by(2)
                        .filter_map(|&m| point(m))
                        .collect::<Vec<_>>()
                });
                let mine: Vec<DevPoint> = factors
                    .iter()
                    .step_by(2)
                    .filter_map(|&m| point(m))
                    .collect();
                (mine, other.join().expect("deviation worker panicked"))
            });
            a.extend(b);
            a.sort_by_key(|p| p.m);
            a
        } else {
            factors.iter().filter_map(|&m| point(m)).collect()
        };
    // EDF: noise type per tau from the local slope of this curve (or the given type).
    let slopes: Vec<f64> = (0..points.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(points.len() - 1));
            if a == b {
                -0.5
            } else {
                (points[b].dev / points[a].dev).ln() / (points[b].tau_s / points[a].tau_s).ln()
            }
        })
        .collect();
    for (p, slope) in points.iter_mut().zip(slopes) {
        let noise = options.noise.unwrap_or_else(|| {
            let s = if kind == Kind::Tdev {
                slope - 1.0
            } else {
                slope
            };
            NoiseType::from_adev_slope(s)
        });
        p.edf = match kind {
            Kind::Oadev => edf_oadev(n, p.m, noise),
            // Conservative: one degree of freedom per non-overlapping difference.
            Kind::Adev | Kind::Hdev => p.n_terms as f64,
            Kind::Ohdev => ((n - 1) / p.m).saturating_sub(2).max(1) as f64,
            Kind::Mdev | Kind::Tdev => ((n - 1) / p.m).saturating_sub(2).max(1) as f64,
            Kind::Totdev => edf_oadev(n, p.m, noise),
        };
        let (lo, hi) = confidence_interval(p.dev, p.edf, options.confidence);
        p.dev_lo = lo;
        p.dev_hi = hi;
    }
    Ok(DevCurve {
        kind,
        tau0_s,
        confidence: options.confidence,
        points,
    })
}

/// Bounded-memory overlapping Allan deviation at octave taus, fed one rate sample at a time.
///
/// Keeps a ring of the last `2 m_max + 1` phase values and, per octave m = 2^k <= `m_max`, the
/// running sum of squared second differences; memory is O(m_max), independent of the recording
/// length, and the cost is O(log m_max) per sample. Results equal [`deviation`] with
/// [`Kind::Oadev`] and [`TauSet::Octave`] (same phase integration, same summation order, up to
/// the batch's four-way accumulator split).
#[derive(Debug, Clone)]
pub struct StreamingOadev {
    tau0_s: f64,
    ring: Vec<f64>,
    mask: usize,
    n_phase: usize,
    rate_sum: f64,
    sums: Vec<f64>,
    counts: Vec<usize>,
}

impl StreamingOadev {
    /// A new accumulator for rate data at period `tau0_s`, with octave taus up to
    /// `max_m` samples (rounded down to a power of two; at least 1).
    pub fn new(tau0_s: f64, max_m: usize) -> Self {
        let levels = usize::BITS - max_m.max(1).leading_zeros();
        let size = (2usize << (levels - 1)) * 2;
        let mut ring = vec![0.0; size];
        ring[0] = 0.0;
        StreamingOadev {
            tau0_s,
            ring,
            mask: size - 1,
            n_phase: 1,
            rate_sum: 0.0,
            sums: vec![0.0; levels as usize],
            counts: vec![0; levels as usize],
        }
    }

    /// Adds one rate sample.
    pub fn push(&mut self, y: f64) {
        self.rate_sum += y;
        let x = self.rate_sum * self.tau0_s;
        let n = self.n_phase;
        self.ring[n & self.mask] = x;
        self.n_phase += 1;
        for (k, (sum, count)) in self.sums.iter_mut().zip(&mut self.counts).enumerate() {
            let m = 1usize << k;
            if n < 2 * m {
                break;
            }
            let d = x - 2.0 * self.ring[(n - m) & self.mask] + self.ring[(n - 2 * m) & self.mask];
            *sum += d * d;
            *count += 1;
        }
    }

    /// Adds many rate samples.
    pub fn extend(&mut self, ys: &[f64]) {
        for &y in ys {
            self.push(y);
        }
    }

    /// Rate samples seen so far.
    pub fn n_samples(&self) -> usize {
        self.n_phase - 1
    }

    /// The OADEV curve so far (taus with at least one term), with EDF and intervals as in
    /// [`deviation`] using `noise` (or the local slope if `None`).
    pub fn curve(&self, confidence: f64, noise: Option<NoiseType>) -> DevCurve {
        let mut points: Vec<DevPoint> = self
            .sums
            .iter()
            .zip(&self.counts)
            .enumerate()
            .filter(|(_, (_, c))| **c > 0)
            .map(|(k, (s, &c))| {
                let m = 1usize << k;
                let tau = m as f64 * self.tau0_s;
                DevPoint {
                    m,
                    tau_s: tau,
                    dev: (s / (2.0 * c as f64 * tau * tau)).sqrt(),
                    n_terms: c,
                    edf: 0.0,
                    dev_lo: 0.0,
                    dev_hi: 0.0,
                }
            })
            .collect();
        let devs: Vec<(f64, f64)> = points.iter().map(|p| (p.tau_s, p.dev)).collect();
        for (i, p) in points.iter_mut().enumerate() {
            let noise = noise.unwrap_or_else(|| {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(devs.len() - 1));
                let slope = if a == b {
                    -0.5
                } else {
                    (devs[b].1 / devs[a].1).ln() / (devs[b].0 / devs[a].0).ln()
                };
                NoiseType::from_adev_slope(slope)
            });
            p.edf = edf_oadev(self.n_phase, p.m, noise);
            (p.dev_lo, p.dev_hi) = confidence_interval(p.dev, p.edf, confidence);
        }
        DevCurve {
            kind: Kind::Oadev,
            tau0_s: self.tau0_s,
            confidence,
            points,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_quantiles_are_close_to_tables() {
        // chi2 tables: nu=10: p=0.025 -> 3.247, p=0.975 -> 20.483; nu=100: 74.22, 129.56.
        for (p, nu, want) in [
            (0.025, 10.0, 3.247),
            (0.975, 10.0, 20.483),
            (0.025, 100.0, 74.222),
            (0.975, 100.0, 129.561),
        ] {
            let got = chi2_quantile(p, nu);
            assert!(
                (got / want - 1.0).abs() < 0.01,
                "p {p} nu {nu}: {got} vs {want}"
            );
        }
        assert!((normal_quantile(0.975) - 1.95996).abs() < 5e-4);
    }

    #[test]
    fn tau_sets() {
        assert_eq!(TauSet::Octave.factors(10), vec![1, 2, 4, 8]);
        assert_eq!(
            TauSet::PerDecade(3).factors(100),
            vec![1, 2, 5, 10, 22, 46, 100]
        );
        assert_eq!("5-per-decade".parse::<TauSet>(), Ok(TauSet::PerDecade(5)));
        assert!("x".parse::<TauSet>().is_err());
    }

    /// Every kernel path (octave runs, other tau groups, per-tau leftovers, block edges, vector
    /// tails) on both the scalar and the best SIMD instruction set, against the plain sum.
    #[test]
    fn second_difference_kernels_equal_the_plain_sum() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut walk = 0.0;
        let x: Vec<f64> = (0..2 * BLOCK + 1237)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                walk += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                walk
            })
            .collect();
        let plain = |m: usize| -> f64 {
            (0..x.len() - 2 * m)
                .map(|i| {
                    let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                    d * d
                })
                .sum()
        };
        let max_m = (x.len() - 1) / 2;
        for ms in [
            TauSet::Octave.factors(max_m),
            TauSet::PerDecade(7).factors(max_m),
            vec![
                1, 2, 3, 5, 6, 12, 24, 25, 50, 100, 101, 202, 404, 808, 1616, 3232, max_m,
            ],
            vec![max_m],
        ] {
            let range = 0..x.len() - 2 * ms[0];
            let scalar = pulp::Scalar::new().vectorize(BlockedPass {
                x: &x,
                ms: &ms,
                range: range.clone(),
            });
            let best = Arch::new().dispatch(BlockedPass {
                x: &x,
                ms: &ms,
                range,
            });
            for (k, &m) in ms.iter().enumerate() {
                let want = plain(m);
                for got in [scalar[k], best[k], second_difference_sum_sq(&x, m)] {
                    assert!((got / want - 1.0).abs() < 1e-12, "m {m}: {got} vs {want}");
                }
            }
        }
    }

    /// A long series (phase on two threads, in the huge-page array, sums on two threads) gives
    /// the same curve as its phase in a plain `Vec`, and the same sums as one thread.
    #[test]
    fn long_series_phase_array_equals_the_vec_phase() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let y: Vec<f64> = (0..PARALLEL_MIN_PHASE_POINTS + 4321)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let mut mapped = LongArray::zeros(y.len() + 1);
        assert!(matches!(mapped, LongArray::Mapped(_)));
        integrate_into(&y, 0.01, &mut mapped);
        let plain = phase_from_rate(&y, 0.01);
        assert!(mapped.iter().eq(plain.iter()));
        let o = Options::default();
        let a = deviation(Kind::Oadev, &y, 0.01, &o).expect("long");
        let b = deviation_from_phase(Kind::Oadev, &plain, 0.01, &o).expect("long");
        assert_eq!(a, b);
        // The two-thread chunked sums equal one single-threaded pass.
        let ms = TauSet::Octave.factors(Kind::Oadev.max_m(plain.len()));
        let one = Arch::new().dispatch(BlockedPass {
            x: &plain,
            ms: &ms,
            range: 0..plain.len() - 2,
        });
        for (p, q) in oadev_sums(&plain, &ms).iter().zip(&one) {
            assert!((p / q - 1.0).abs() < 1e-12, "{p} vs {q}");
        }
    }

    #[test]
    fn errors_say_what_is_wrong() {
        let o = Options::default();
        assert!(matches!(
            deviation(Kind::Oadev, &[1.0], 1.0, &o),
            Err(AllanError::TooShort { .. })
        ));
        assert!(matches!(
            deviation(Kind::Oadev, &[1.0, 2.0, 3.0], 0.0, &o),
            Err(AllanError::BadPeriod { .. })
        ));
    }
}
