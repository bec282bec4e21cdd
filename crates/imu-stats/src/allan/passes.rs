//! The fused passes over the phase behind every kind but OADEV/TOTDEV (`kernels.rs`): the
//! non-overlapping ADEV/HDEV sums, OHDEV's overlapping third differences and MDEV/TDEV's
//! running recurrence, each computing all its taus in one cache-blocked pass (a block of `x`
//! is read from memory once and used by every tau while it is in cache), on two threads for
//! long series.
//!
//! Each difference term is computed with the same operations, in the same order, as the plain
//! formula (`second_difference`, `third_difference`): the phase of a long record is large
//! against its differences, so a reassociated term would round differently (relative to the
//! term, by about eps |x| / |d|). Only the order in which the squared terms are added differs
//! from a plain loop. MDEV's recurrence is serial per tau; it runs as eight interleaved chains
//! in SIMD lanes ([`ModifiedLanes`]), on AVX2 in one fused loop from the phase to the lanes
//! (`advance_fused`, bit-identical to the scratch-array path the other CPUs take).

use std::sync::atomic::{AtomicUsize, Ordering};

use pulp::{Arch, Simd, WithSimd};

use super::kernels::{BLOCK, GROUP, PARALLEL_MIN_PHASE_POINTS, UNROLL, sum_by};

/// x[i+2m] - 2 x[i+m] + x[i], the Allan second difference.
#[inline(always)]
pub(super) fn second_difference(x: &[f64], i: usize, m: usize) -> f64 {
    x[i + 2 * m] - 2.0 * x[i + m] + x[i]
}

/// x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i], the Hadamard third difference.
#[inline(always)]
pub(super) fn third_difference(x: &[f64], i: usize, m: usize) -> f64 {
    x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i]
}

/// The difference of order `D` (2 or 3) at `i`, lag `m`.
#[inline(always)]
fn difference<const D: usize>(x: &[f64], i: usize, m: usize) -> f64 {
    if D == 2 {
        second_difference(x, i, m)
    } else {
        third_difference(x, i, m)
    }
}

/// Sums the outputs of `pass` over `0..end` (each a vector of `n_out` sums): one call for
/// short series; for long ones two threads take chunks of the range from a shared counter (a
/// thread that loses its core does not hold the other up) and the chunks' sums are added in
/// chunk order, so the result does not depend on which thread took which chunk.
pub(super) fn chunked_sums(
    x_len: usize,
    end: usize,
    n_out: usize,
    pass: impl Fn(std::ops::Range<usize>) -> Vec<f64> + Sync,
) -> Vec<f64> {
    if x_len < PARALLEL_MIN_PHASE_POINTS {
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
    let mut sums = vec![0.0; n_out];
    for (_, part) in &chunks {
        for (s, p) in sums.iter_mut().zip(part) {
            *s += p;
        }
    }
    sums
}

/// Squared differences of order `D` at lag `m` for each of `G` taus `ms`, summed over every
/// `i` in `lo..hi` (`hi + D max(ms) <= x.len()`), on SIMD vectors: the shared `x[i]` is loaded
/// once per step, each tau's term with the plain formula's operations (no fused multiply-add
/// inside the difference).
#[inline(always)]
fn overlapping_group_sums<S: Simd, const D: usize, const G: usize>(
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
    let lag = |k: usize| -> [&[S::f64s]; G] { std::array::from_fn(|j| &at(k * ms[j])[..n_vec]) };
    let (first, second, third) = (lag(1), lag(2), lag(D.min(3)));
    let coef = simd.splat_f64s(D as f64);
    let zero = simd.splat_f64s(0.0);
    let mut acc = [[zero; G]; UNROLL];
    for v in (0..n_vec).step_by(UNROLL) {
        for (u, acc) in acc.iter_mut().enumerate() {
            let a = base[v + u];
            for (j, acc) in acc.iter_mut().enumerate() {
                let w = v + u;
                let d = if D == 2 {
                    // (x2 - 2 x1) + x0
                    simd.add_f64s(
                        simd.sub_f64s(second[j][w], simd.mul_f64s(coef, first[j][w])),
                        a,
                    )
                } else {
                    // ((x3 - 3 x2) + 3 x1) - x0
                    simd.sub_f64s(
                        simd.add_f64s(
                            simd.sub_f64s(third[j][w], simd.mul_f64s(coef, second[j][w])),
                            simd.mul_f64s(coef, first[j][w]),
                        ),
                        a,
                    )
                };
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
        simd.reduce_sum_f64s(v)
            + (done..hi)
                .map(|i| {
                    let d = difference::<D>(x, i, ms[j]);
                    d * d
                })
                .sum::<f64>()
    })
}

/// One blocked pass of the overlapping third-difference sums (OHDEV) for increasing `ms` over
/// `i` in `range`: groups of up to [`GROUP`] taus share each block of `x` while it is in cache.
pub(super) struct OverlappingThirdPass<'a> {
    pub(super) x: &'a [f64],
    pub(super) ms: &'a [usize],
    pub(super) range: std::ops::Range<usize>,
}

impl WithSimd for OverlappingThirdPass<'_> {
    type Output = Vec<f64>;

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) -> Vec<f64> {
        let OverlappingThirdPass { x, ms, range } = self;
        let mut sums = vec![0.0; ms.len()];
        let mut i0 = range.start;
        while i0 < range.end {
            let i1 = (i0 + BLOCK).min(range.end);
            for (taus, out) in ms.chunks(GROUP).zip(sums.chunks_mut(GROUP)) {
                // All taus of the group have terms up to the largest tau's end; the smaller
                // taus' remaining terms in this block are summed one tau at a time.
                let hi = i1.min(x.len() - 3 * taus[taus.len() - 1]);
                if hi > i0 {
                    macro_rules! run {
                        ($n:literal) => {
                            overlapping_group_sums::<S, 3, $n>(simd, x, taus, i0, hi)
                                .iter()
                                .zip(out.iter_mut())
                                .for_each(|(s, o)| *o += s)
                        };
                    }
                    match taus.len() {
                        1 => run!(1),
                        2 => run!(2),
                        3 => run!(3),
                        _ => run!(4),
                    }
                }
                for (o, &m) in out.iter_mut().zip(taus) {
                    let (lo, end) = (hi.max(i0), i1.min(x.len() - 3 * m));
                    if end > lo {
                        *o += overlapping_group_sums::<S, 3, 1>(simd, x, &[m], lo, end)[0];
                    }
                }
            }
            i0 = i1;
        }
        sums
    }
}

/// Overlapping Hadamard sums: for each increasing `m` in `ms` (`3 m <= x.len() - 1`) the sum
/// over all i of the squared third difference at lag m.
pub(super) fn overlapping_third_sums(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let Some(&m_min) = ms.first() else {
        return Vec::new();
    };
    let arch = Arch::new();
    chunked_sums(x.len(), x.len() - 3 * m_min, ms.len(), |range| {
        arch.dispatch(OverlappingThirdPass { x, ms, range })
    })
}

/// One blocked pass of the non-overlapping sums of order `D` over `i` in `range`.
pub(super) struct NonOverlappingPass<'a, const D: usize> {
    pub(super) x: &'a [f64],
    pub(super) ms: &'a [usize],
    pub(super) range: std::ops::Range<usize>,
}

impl<const D: usize> WithSimd for NonOverlappingPass<'_, D> {
    type Output = Vec<f64>;

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) -> Vec<f64> {
        let NonOverlappingPass { x, ms, range } = self;
        let mut sums = vec![0.0; ms.len()];
        let mut i0 = range.start;
        while i0 < range.end {
            let i1 = (i0 + BLOCK).min(range.end);
            for (out, &m) in sums.iter_mut().zip(ms) {
                // Terms at i = 0, m, 2m, ... while the window fits (i <= len - 1 - D m).
                let end = i1.min(x.len() - D * m);
                let first = i0.div_ceil(m) * m;
                if first >= end {
                    continue;
                }
                *out += if m == 1 {
                    overlapping_group_sums::<S, D, 1>(simd, x, &[1], first, end)[0]
                } else {
                    sum_by((first..end).step_by(m), |i| {
                        let d = difference::<D>(x, i, m);
                        d * d
                    })
                };
            }
            i0 = i1;
        }
        sums
    }
}

/// Non-overlapping sums of order `D` (2: ADEV, 3: HDEV): for each `m` in `ms` (`D m <=
/// x.len() - 1`) the sum over i = 0, m, 2m, ... of the squared difference at lag m. One
/// blocked pass for all taus: at octave taus the short taus would otherwise each stream the
/// whole phase, and the long ones touch a cache line per term.
pub(super) fn non_overlapping_sums<const D: usize>(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let Some(&m_min) = ms.iter().min() else {
        return Vec::new();
    };
    let arch = Arch::new();
    chunked_sums(x.len(), x.len() - D * m_min, ms.len(), |range| {
        arch.dispatch(NonOverlappingPass::<D> { x, ms, range })
    })
}

/// Lanes of the MDEV recurrence (v_j for eight consecutive j at once: two AVX2 vectors, so
/// two chains of vector additions overlap).
pub(super) const LANES: usize = 8;

/// j per block of the MDEV pass: every tau advances through a block before the next, so a
/// block's four lagged 64 KiB windows of `x` per tau (shared between octave taus) stay in the
/// per-core L2 cache while the taus use them (8,192 took 15-20 % less CPU than 2,048 and
/// 32,768 on the 10 M-point bench series).
const MDEV_BLOCK: usize = 8192;

/// One tau's MDEV recurrence (see [`modified_sums`]) over rows `row0..row_end` of `LANES`
/// consecutive v_j (row r holds v_{8r} ..= v_{8r+7}), eight per step:
/// v_{j+8} = v_j + (w_j + w_{j+4}), w_j = (t_j + t_{j+1}) + (t_{j+2} + t_{j+3}) with t the
/// third differences, so eight independent chains advance together in SIMD vectors (the plain
/// recurrence is one chain of dependent additions, about 4 cycles per term).
struct ModifiedLanes {
    m: usize,
    /// Number of v_j (n - 3m + 1).
    terms: usize,
    /// Whole rows of v_j (`terms / LANES`).
    rows: usize,
    /// This part's rows end here (exclusive); the last part (`row_end == rows`) also takes the
    /// fewer than `LANES` v_j after the last row.
    row_end: usize,
    /// The row at `lanes` (the next to add).
    row: usize,
    /// v_{8 row + l}.
    lanes: [f64; LANES],
    /// Sums of the squared v_j of each lane so far.
    acc: [f64; LANES],
}

impl ModifiedLanes {
    /// The part of tau `m`'s rows `row0..row_end` (`terms >= 2 LANES`, see
    /// `modified_sum_plain` for fewer): its first v_j summed directly (O(m)), the next seven by
    /// the plain recurrence.
    fn new(x: &[f64], m: usize, row0: usize, row_end: usize) -> Self {
        let terms = x.len() - 3 * m + 1;
        let j0 = row0 * LANES;
        let mut lanes = [window_sum(x, j0, m); LANES];
        for l in 1..LANES {
            lanes[l] = lanes[l - 1] + third_step(x, j0 + l - 1, m);
        }
        ModifiedLanes {
            m,
            terms,
            rows: terms / LANES,
            row_end,
            row: row0,
            lanes,
            acc: [0.0; LANES],
        }
    }

    /// Adds the rows before `stop` (clipped to this part's), with `t` and `w` as scratch.
    #[inline(always)]
    fn advance(&mut self, x: &[f64], stop: usize, t: &mut [f64], w: &mut [f64]) {
        let (r0, r1) = (self.row, stop.min(self.row_end));
        if r1 <= r0 {
            return;
        }
        let m = self.m;
        let j0 = r0 * LANES;
        // The part's last row needs no step after it.
        let last = r1 == self.row_end;
        let steps = (r1 - r0 - usize::from(last)) * LANES;
        let len = steps + LANES - 1;
        let t = &mut t[..len];
        let (x0, x1, x2, x3) = (
            &x[j0..j0 + len],
            &x[j0 + m..j0 + m + len],
            &x[j0 + 2 * m..j0 + 2 * m + len],
            &x[j0 + 3 * m..j0 + 3 * m + len],
        );
        for ((((t, &a), &b), &c), &d) in t.iter_mut().zip(x0).zip(x1).zip(x2).zip(x3) {
            *t = (d - 3.0 * c) + (3.0 * b - a);
        }
        // Fours then eights (`w` is `steps + 4` long).
        let w = &mut w[..steps + 4];
        for (k, w) in w.iter_mut().enumerate() {
            *w = (t[k] + t[k + 1]) + (t[k + 2] + t[k + 3]);
        }
        for k in 0..steps {
            w[k] += w[k + 4];
        }
        let (mut lanes, mut acc) = (self.lanes, self.acc);
        for step in w[..steps].chunks_exact(LANES) {
            for l in 0..LANES {
                acc[l] += lanes[l] * lanes[l];
                lanes[l] += step[l];
            }
        }
        if last {
            for l in 0..LANES {
                acc[l] += lanes[l] * lanes[l];
            }
        }
        (self.lanes, self.acc, self.row) = (lanes, acc, r1);
    }

    /// [`Self::advance`] as one fused loop from the phase to the lanes (no scratch arrays), on
    /// AVX2: the rows before `stop` that have a step after them and whose loads stay inside `x`
    /// (all but the last few rows of a tau); [`Self::advance`] takes the rest. Every value is
    /// computed with the same operations in the same order as there (the sums of two, four and
    /// eight third differences are formed in registers, the neighbours by lane shuffles), so
    /// the result is bit-identical to the scratch path's.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn advance_fused(&mut self, simd: pulp::x86::V3, x: &[f64], stop: usize) {
        let (r0, r1) = (self.row, stop.min(self.row_end));
        if r1 <= r0 {
            return;
        }
        let m = self.m;
        let j0 = r0 * LANES;
        // Row i reads the third differences t_k up to k = 8 i + 19 (four vectors ahead), so
        // x up to j0 + 8 i + 19 + 3 m.
        let in_bounds = x.len().saturating_sub(j0 + 3 * m + 20) / LANES;
        let rows = (r1 - r0 - usize::from(r1 == self.row_end)).min(in_bounds);
        if rows == 0 {
            return;
        }
        let len = rows * LANES + 20;
        let lag = |k: usize| pulp::x86::V3::as_simd_f64s(&x[j0 + k * m..j0 + k * m + len]).0;
        let (x0, x1, x2, x3) = (lag(0), lag(1), lag(2), lag(3));
        let three = simd.splat_f64s(3.0);
        // t_{4q..4q+4}: (x3 - 3 x2) + (3 x1 - x0), as `third_step`.
        macro_rules! t {
            ($q:expr) => {
                simd.add_f64s(
                    simd.sub_f64s(x3[$q], simd.mul_f64s(three, x2[$q])),
                    simd.sub_f64s(simd.mul_f64s(three, x1[$q]), x0[$q]),
                )
            };
        }
        // Pairs p_k = t_k + t_{k+1}, fours w_k = p_k + p_{k+2} ((t_k + t_{k+1}) + (t_{k+2} +
        // t_{k+3}) as in `advance`), eights w_k + w_{k+4}.
        let (t0, t1) = (t!(0), t!(1));
        let mut tn = t!(2);
        let p0 = simd.add_f64s(t0, on_one(simd, t0, t1));
        let mut p = simd.add_f64s(t1, on_one(simd, t1, tn));
        let mut w = simd.add_f64s(p0, on_two(simd, p0, p));
        let (mut lo, mut hi) = (quad(&self.lanes, 0), quad(&self.lanes, 4));
        let (mut acc_lo, mut acc_hi) = (quad(&self.acc, 0), quad(&self.acc, 4));
        // The next eight-sum w_{4q} + w_{4q+4}, from t up to 4q + 15.
        macro_rules! eight {
            ($q:expr) => {{
                let t_next = t!($q + 3);
                let p_next = simd.add_f64s(tn, on_one(simd, tn, t_next));
                let w_next = simd.add_f64s(p, on_two(simd, p, p_next));
                let e = simd.add_f64s(w, w_next);
                (tn, p, w) = (t_next, p_next, w_next);
                e
            }};
        }
        for i in 0..rows {
            let e = eight!(2 * i);
            acc_lo = simd.add_f64s(acc_lo, simd.mul_f64s(lo, lo));
            lo = simd.add_f64s(lo, e);
            let e = eight!(2 * i + 1);
            acc_hi = simd.add_f64s(acc_hi, simd.mul_f64s(hi, hi));
            hi = simd.add_f64s(hi, e);
        }
        self.lanes = [lo.0, lo.1, lo.2, lo.3, hi.0, hi.1, hi.2, hi.3];
        self.acc = [
            acc_lo.0, acc_lo.1, acc_lo.2, acc_lo.3, acc_hi.0, acc_hi.1, acc_hi.2, acc_hi.3,
        ];
        self.row = r0 + rows;
    }

    /// This part's sum of v_j^2, once all its rows are added; the last part adds the fewer
    /// than `LANES` v_j after the last row, from v_{8 rows - 1}.
    fn finish(&self, x: &[f64]) -> f64 {
        let a = self.acc;
        let mut s = ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]));
        if self.row_end == self.rows {
            let mut v = self.lanes[LANES - 1];
            for j in self.rows * LANES - 1..self.terms - 1 {
                v += third_step(x, j, self.m);
                s += v * v;
            }
        }
        s
    }
}

/// Lanes `o..o + 4` of `a` as one AVX2 vector.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn quad(a: &[f64; LANES], o: usize) -> pulp::f64x4 {
    pulp::f64x4(a[o], a[o + 1], a[o + 2], a[o + 3])
}

/// [a2, a3, b0, b1]: the four values two places on from `a` in the sequence `a`, `b`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn on_two(simd: pulp::x86::V3, a: pulp::f64x4, b: pulp::f64x4) -> pulp::f64x4 {
    pulp::cast(
        simd.avx
            ._mm256_permute2f128_pd::<0x21>(pulp::cast(a), pulp::cast(b)),
    )
}

/// [a1, a2, a3, b0]: the four values one place on.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn on_one(simd: pulp::x86::V3, a: pulp::f64x4, b: pulp::f64x4) -> pulp::f64x4 {
    pulp::cast(
        simd.avx
            ._mm256_shuffle_pd::<0b0101>(pulp::cast(a), pulp::cast(on_two(simd, a, b))),
    )
}

/// v_j = sum over i in j..j + m of the second difference at lag m, summed as
/// `sum_by(j..j + m, ..)` does (term k into accumulator k mod 4, the four added pairwise), so
/// bit-identical to it, but on contiguous slices the compiler vectorizes (the long taus' first
/// v_j are millions of terms).
fn window_sum(x: &[f64], j: usize, m: usize) -> f64 {
    let (x0, x1, x2) = (&x[j..j + m], &x[j + m..j + 2 * m], &x[j + 2 * m..j + 3 * m]);
    let mut acc = [0.0f64; 4];
    let (c0, c1, c2) = (x0.chunks_exact(4), x1.chunks_exact(4), x2.chunks_exact(4));
    let tail = m / 4 * 4;
    for ((a, b), c) in c0.zip(c1).zip(c2) {
        for l in 0..4 {
            acc[l] += c[l] - 2.0 * b[l] + a[l];
        }
    }
    for k in tail..m {
        acc[k & 3] += x2[k] - 2.0 * x1[k] + x0[k];
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// The recurrence's step v_{j+1} - v_j, a third difference (allantools' operations).
#[inline(always)]
fn third_step(x: &[f64], j: usize, m: usize) -> f64 {
    (x[j + 3 * m] - 3.0 * x[j + 2 * m]) + (3.0 * x[j + m] - x[j])
}

/// One tau's MDEV sum by the plain recurrence (for fewer than `2 LANES` terms).
pub(super) fn modified_sum_plain(x: &[f64], m: usize) -> f64 {
    let terms = x.len() - 3 * m + 1;
    let mut v = sum_by(0..m, |i| second_difference(x, i, m));
    let mut s = v * v;
    for j in 0..terms - 1 {
        v += third_step(x, j, m);
        s += v * v;
    }
    s
}

/// Part `part` of `parts` of the MDEV sums of `ms` (each long enough for [`ModifiedLanes`]) in
/// one blocked pass: each block of j advances every tau, so the blocks of `x` that taus share
/// (octave taus' lags 2m, 4m, ... are other taus' lags) are read from memory once. Part k of a
/// tau covers its rows k rows / parts .. (k + 1) rows / parts.
pub(super) struct ModifiedPass<'a> {
    pub(super) x: &'a [f64],
    pub(super) ms: &'a [usize],
    pub(super) part: usize,
    pub(super) parts: usize,
    /// Use the fused AVX2 loop where the CPU has it (`false`: the scratch path alone, which
    /// the tests compare it with).
    pub(super) fuse: bool,
}

impl WithSimd for ModifiedPass<'_> {
    type Output = Vec<f64>;

    #[inline(always)]
    fn with_simd<S: Simd>(self, _simd: S) -> Vec<f64> {
        let ModifiedPass {
            x,
            ms,
            part,
            parts,
            fuse,
        } = self;
        // The fused loop needs AVX2's lane shuffles; `modified_sums` runs this under
        // `Arch::dispatch`, which picks the same instruction set where the CPU has it.
        #[cfg(target_arch = "x86_64")]
        let fused = pulp::x86::V3::try_new().filter(|_| fuse);
        #[cfg(not(target_arch = "x86_64"))]
        let _ = fuse;
        let mut states: Vec<ModifiedLanes> = ms
            .iter()
            .map(|&m| {
                let rows = (x.len() - 3 * m + 1) / LANES;
                let at = |k: usize| k * rows / parts;
                ModifiedLanes::new(x, m, at(part), at(part + 1))
            })
            .collect();
        let start = states.iter().map(|s| s.row).min().unwrap_or(0);
        let end = states.iter().map(|s| s.row_end).max().unwrap_or(0);
        let (mut t, mut w) = (vec![0.0; MDEV_BLOCK + LANES], vec![0.0; MDEV_BLOCK + 4]);
        let mut r = start;
        while r < end {
            let stop = (r + MDEV_BLOCK / LANES).min(end);
            for st in &mut states {
                #[cfg(target_arch = "x86_64")]
                if let Some(v3) = fused {
                    st.advance_fused(v3, x, stop);
                }
                st.advance(x, stop, &mut t, &mut w);
            }
            r = stop;
        }
        states.iter().map(|st| st.finish(x)).collect()
    }
}

/// Sum over j of v_j^2, v_j = sum_{i=j}^{j+m-1} (x[i+2m] - 2 x[i+m] + x[i]), for each `m` in
/// increasing `ms` (`3 m <= x.len() - 1`): the modified Allan variance's numerator. Each v_j is
/// the previous one plus a third difference of `x` (the recurrence allantools uses), so the sum
/// only ever adds small phase differences. The alternative, differences of the running sum of
/// `x`, cancels catastrophically: that running sum grows like N^2 times the frequency offset,
/// and on a 10 M-sample record with a random-walk rate it left MDEV/TDEV 4.2e-6 (relative) from
/// allantools, which agrees with an extended-precision reference to 1e-12; this recurrence
/// agrees with allantools to 2e-11 (BENCHMARKS.md, issue 24). The recurrence runs on eight
/// lanes ([`ModifiedLanes`]) and, for long series, on two threads each taking half of every
/// tau's v_j (the second half starts from a direct sum): the result differs from the plain
/// serial loop by the rounding of a different order of additions (1e-13 relative on the 10 M
/// point bench series).
pub(super) fn modified_sums(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let arch = Arch::new();
    // The lanes need at least two rows per part.
    let long: Vec<usize> = ms
        .iter()
        .copied()
        .filter(|&m| x.len() - 3 * m + 1 >= 4 * LANES)
        .collect();
    let sums = if x.len() < PARALLEL_MIN_PHASE_POINTS {
        arch.dispatch(ModifiedPass {
            x,
            ms: &long,
            part: 0,
            parts: 1,
            fuse: true,
        })
    } else {
        let pass = |part| {
            arch.dispatch(ModifiedPass {
                x,
                ms: &long,
                part,
                parts: 2,
                fuse: true,
            })
        };
        let (a, b) = std::thread::scope(|scope| {
            let other = scope.spawn(|| pass(1));
            (pass(0), other.join().expect("deviation worker panicked"))
        });
        a.iter().zip(&b).map(|(a, b)| a + b).collect()
    };
    let mut long_sums = sums.into_iter();
    ms.iter()
        .map(|&m| {
            if x.len() - 3 * m + 1 >= 4 * LANES {
                long_sums.next().unwrap_or(f64::NAN)
            } else {
                modified_sum_plain(x, m)
            }
        })
        .collect()
}
