//! Phase integration and the overlapping second-difference sums behind OADEV: cache-blocked,
//! SIMD through `pulp` runtime dispatch, on two threads for long series.

use pulp::{Arch, Simd, WithSimd};

/// Series at least this long (phase points) are computed on two threads.
pub(super) const PARALLEL_MIN_PHASE_POINTS: usize = 1 << 20;

/// Integrates rate data into phase: `x[0] = 0`, `x[i+1] = tau0 * (y[0] + ... + y[i])`.
pub fn phase_from_rate(y: &[f64], tau0_s: f64) -> Vec<f64> {
    let mut x = vec![0.0; y.len() + 1];
    integrate_into(y, tau0_s, &mut x);
    x
}

/// [`phase_from_rate`] into `x` (`y.len() + 1` long; `x[0]` is set to 0).
pub(super) fn integrate_into(y: &[f64], tau0_s: f64, x: &mut [f64]) {
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
pub(super) enum LongArray {
    Heap(Vec<f64>),
    Mapped(memmap2::MmapMut),
}

impl LongArray {
    /// `len` zeros.
    pub(super) fn zeros(len: usize) -> Self {
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
pub(super) fn sum_by(idx: impl Iterator<Item = usize>, f: impl Fn(usize) -> f64) -> f64 {
    let mut acc = [0.0f64; 4];
    for (k, i) in idx.enumerate() {
        acc[k & 3] += f(i);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Taus per pass of the second-difference kernels: a block of `x` is read once for up to this
/// many taus, and `UNROLL` x `GROUP` accumulators still fit the 16 vector registers of AVX2.
pub(super) const GROUP: usize = 4;

/// Independent SIMD vectors per loop step (so the fused multiply-add latency is hidden).
pub(super) const UNROLL: usize = 2;

/// Elements of `i` per block of the blocked pass (128 KiB of `x` per stream: the streams of one
/// group of taus stay in the per-core L2 cache while the group uses them).
pub(super) const BLOCK: usize = 16384;

/// Second-difference sums of an octave run of taus `m, 2m, ..., 2^(G-1) m` over `i` in `lo..hi`
/// (`hi + 2^G m <= x.len()`). With `e_k = x[i + 2^k m] - x[i]` the run's second differences are
/// `e_(k+1) - 2 e_k`, so one vector step loads `G + 2` vectors (not `3 G`) and spends a
/// subtraction and two multiply-adds per tau. Written on `pulp` SIMD vectors so it compiles to
/// AVX2/FMA where the CPU has it (see [`oadev_sums`]); the scalar instance of `S` is the plain
/// code the baseline target vectorizes on its own.
#[inline(always)]
pub(super) fn octave_run_sums<S: Simd, const G: usize>(
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
pub(super) fn tau_group_sums<S: Simd, const G: usize>(
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
pub(super) struct TauGroup {
    start: usize,
    len: usize,
    /// Each tau is twice the previous one (the octave-run kernel applies).
    octave: bool,
}

/// Splits increasing `ms` into octave runs and other groups of at most [`GROUP`] taus.
pub(super) fn tau_groups(ms: &[usize]) -> Vec<TauGroup> {
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
pub(super) struct BlockedPass<'a> {
    pub(super) x: &'a [f64],
    pub(super) ms: &'a [usize],
    pub(super) range: std::ops::Range<usize>,
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
/// baseline instructions otherwise), on two threads for long series (chunks of `i` from a
/// shared counter, `passes::chunked_sums`).
pub(super) fn oadev_sums(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let Some(&m_min) = ms.first() else {
        return Vec::new();
    };
    let arch = Arch::new();
    super::passes::chunked_sums(x.len(), x.len() - 2 * m_min, ms.len(), |range| {
        arch.dispatch(BlockedPass { x, ms, range })
    })
}
