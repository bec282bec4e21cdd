//! Theo1 sums at many averaging factors at once from shared lagged products (issue 24): TheoBR's
//! bias ratio needs Theo1 at every m = 12 + 4i up to 0.13 N, which as separate double sums costs
//! O(N^3 / 900).
//!
//! Each squared term of SP 1065 eq. (30), t = x_i - x_{i+u} + x_{i+m} - x_{i+m-u}, expands into
//! four squares and six products at lags u, m, m - u and m - 2u, each summed over a window of
//! N - m consecutive i. One pass per lag k of prefix sums of x_i x_{i+k} answers every window of
//! every (m, u) that needs lag k in O(1): about 0.13 N passes of O(N), O(N^2 / 7.5) in all.
//!
//! The expansion subtracts sums of size E = sum x_i^2 to leave a Theo1 sum that can be 10^15
//! times smaller (random-walk FM, or a large frequency offset). So the products are formed
//! exactly (Dekker's two-product) and every sum is kept in double-double (about 106 bits);
//! a worst-case bound on the remaining error, 512 N H(m/2) 2^-106 E, is checked for every m and
//! any m whose bound exceeds 1e-13 of its sum is summed directly instead (the small m, cheap to
//! sum directly, are the ones that can fail it). Results therefore equal the direct double sum
//! to about 1e-13 relative.
//!
//! The double-double arithmetic is written here rather than taken from a crate (`twofloat`):
//! only the error-free sum and product are needed, inlined into the lag passes' lanes, and the
//! product must be Dekker's (no FMA on the baseline x86-64 target) to be the same on every CPU.

/// Lags per pass: one pass reads `x` once for this many lags (independent accumulator lanes, so
/// the double-double additions' dependency chains overlap).
const LANES: usize = 8;

/// Veltkamp's splitting constant 2^27 + 1: splits an f64 into two 26-bit halves.
const SPLITTER: f64 = 134_217_729.0;

/// Unit roundoff squared, 2^-106.
const U2: f64 = 1.232_595_164_407_831e-32;

/// Relative bound the fast sum must meet before it is used instead of the direct double sum.
const MAX_RELATIVE_ERROR: f64 = 1e-13;

/// A double-double number hi + lo, |lo| <= ulp(hi) / 2.
#[derive(Clone, Copy, Default, Debug)]
struct Dd {
    hi: f64,
    lo: f64,
}

#[inline]
fn split(a: f64) -> (f64, f64) {
    let c = SPLITTER * a;
    let h = c - (c - a);
    (h, a - h)
}

/// a + b = s + e exactly (Knuth).
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// a + b = s + e exactly when |a| >= |b| (Dekker).
#[inline]
fn fast_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// a b = p + e exactly, from a and b's precomputed halves (Dekker; no FMA on the baseline target).
#[inline]
fn two_prod(a: f64, (ah, al): (f64, f64), b: f64, (bh, bl): (f64, f64)) -> (f64, f64) {
    let p = a * b;
    (p, ((ah * bh - p) + ah * bl + al * bh) + al * bl)
}

impl Dd {
    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.hi, o.hi);
        let (hi, lo) = fast_two_sum(s, e + (self.lo + o.lo));
        Dd { hi, lo }
    }

    fn sub(self, o: Dd) -> Dd {
        self.add(Dd {
            hi: -o.hi,
            lo: -o.lo,
        })
    }

    fn mul(self, o: Dd) -> Dd {
        let (p, e) = two_prod(self.hi, split(self.hi), o.hi, split(o.hi));
        let (hi, lo) = fast_two_sum(p, e + (self.hi * o.lo + self.lo * o.hi));
        Dd { hi, lo }
    }

    fn scale(self, k: f64) -> Dd {
        // Exact for the powers of two it is used with.
        Dd {
            hi: self.hi * k,
            lo: self.lo * k,
        }
    }

    /// 1 / u to double-double precision.
    fn recip(u: usize) -> Dd {
        let uf = u as f64;
        let hi = 1.0 / uf;
        let (p, e) = two_prod(hi, split(hi), uf, split(uf));
        Dd {
            hi,
            lo: ((1.0 - p) - e) / uf,
        }
    }
}

/// `x` less x_0 + b i, b near its mean slope with few enough significant bits that b i is exact
/// for every i, as double-double (hi, lo) arrays. Theo1 is blind to any phase offset and exactly
/// linear phase, so the sums are unchanged, but a frequency offset (a gyro's bias, gravity on an
/// accelerometer) no longer inflates the energy the expansion's error is relative to.
fn detrended(x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let x0 = x[0];
    let slope = (x[n - 1] - x0) / (n - 1).max(1) as f64;
    // 53 bits less the bits of the largest i.
    let index_bits = usize::BITS - n.leading_zeros();
    let slope = short_mantissa(slope, 52 - index_bits as i32);
    x.iter()
        .enumerate()
        .map(|(i, &v)| {
            let (s1, e1) = two_sum(v, -(slope * i as f64));
            let (s2, e2) = two_sum(s1, -x0);
            fast_two_sum(s2, e1 + e2)
        })
        .unzip()
}

/// `v` rounded to `bits` significant bits (exactly, by power-of-two scaling); 0 for non-finite
/// or zero `v`.
fn short_mantissa(v: f64, bits: i32) -> f64 {
    if !v.is_finite() || v == 0.0 || bits <= 0 {
        return 0.0;
    }
    let exponent = v.abs().log2().floor() as i32;
    let scale = 2f64.powi(bits - 1 - exponent);
    (v * scale).round() / scale
}

/// Prefix sums P(j) = sum over i < j of x_i x_{i+k} for `LANES` consecutive lags, kept only at
/// the positions the windows start or end at: j <= `head_end` and j >= `tail_start`.
struct LagPrefixes {
    head_end: usize,
    tail_start: usize,
    hi: Vec<[f64; LANES]>,
    lo: Vec<[f64; LANES]>,
}

impl LagPrefixes {
    fn at(&self, j: usize, lane: usize) -> Dd {
        let idx = if j <= self.head_end {
            j
        } else {
            debug_assert!(j >= self.tail_start);
            self.head_end + 1 + (j - self.tail_start)
        };
        Dd {
            hi: self.hi[idx][lane],
            lo: self.lo[idx][lane],
        }
    }
}

/// The prefix sums of lags k0..k0 + LANES over the zero-padded double-double phase `xp` + `xl`
/// (`n` points, then at least k0 + LANES zeros), `xs` the halves of `xp`.
fn lag_prefixes(
    xp: &[f64],
    xl: &[f64],
    xs: &[(f64, f64)],
    n: usize,
    k0: usize,
    head_end: usize,
    tail_start: usize,
) -> LagPrefixes {
    let stored = head_end + 1 + (n + 1 - tail_start);
    let mut out = LagPrefixes {
        head_end,
        tail_start,
        hi: Vec::with_capacity(stored),
        lo: Vec::with_capacity(stored),
    };
    let mut sh = [0.0f64; LANES];
    let mut sl = [0.0f64; LANES];
    out.hi.push(sh);
    out.lo.push(sl);
    // Products vanish (zero padding) once i + k0 >= n, so the sums are final there.
    let last = n.saturating_sub(k0);
    for i in 0..n {
        if i < last {
            let (a, al, ah) = (xp[i], xl[i], xs[i]);
            let b = &xp[i + k0..i + k0 + LANES];
            let bl = &xl[i + k0..i + k0 + LANES];
            let bs = &xs[i + k0..i + k0 + LANES];
            for j in 0..LANES {
                // (a + al)(b + bl) to double-double precision (al bl is below it).
                let (p, e) = two_prod(a, ah, b[j], bs[j]);
                let e = e + (a * bl[j] + al * b[j]);
                let (s, e2) = two_sum(sh[j], p);
                let (h, l) = fast_two_sum(s, sl[j] + (e + e2));
                sh[j] = h;
                sl[j] = l;
            }
        }
        if i < head_end || i + 1 >= tail_start {
            out.hi.push(sh);
            out.lo.push(sl);
        }
    }
    out
}

/// Theo1 double sums (SP 1065 eq. (30) before its normalization, as `theo::theo1_sum`) of phase
/// `x` at every even factor in `ms` (each 2 <= m < N), computed together from lagged products;
/// `direct(m)` is the direct double sum, used for any m whose error bound fails (see the module
/// doc). The lag passes are interleaved over two threads when there are enough of them.
pub(super) fn theo1_sums(x: &[f64], ms: &[usize], direct: impl Fn(usize) -> f64) -> Vec<f64> {
    theo1_sums_within(x, ms, MAX_RELATIVE_ERROR, direct)
}

/// [`theo1_sums`] with the relative error bound `max_relative_error` the lag sums must meet.
fn theo1_sums_within(
    x: &[f64],
    ms: &[usize],
    max_relative_error: f64,
    direct: impl Fn(usize) -> f64,
) -> Vec<f64> {
    let n = x.len();
    let Some(&k_max) = ms.iter().max() else {
        return Vec::new();
    };
    debug_assert!(ms.iter().all(|&m| m >= 2 && m.is_multiple_of(2) && m < n));
    let (mut xp, mut xl) = detrended(x);
    xp.resize(n + k_max + 2 * LANES, 0.0);
    xl.resize(n + k_max + 2 * LANES, 0.0);
    let xs: Vec<(f64, f64)> = xp.iter().map(|&v| split(v)).collect();
    let head_end = k_max;
    let tail_start = (n - k_max).max(head_end + 1);
    let recips: Vec<Dd> = (0..=k_max / 2 + 1)
        .map(|u| if u == 0 { Dd::default() } else { Dd::recip(u) })
        .collect();
    let harmonic: Vec<Dd> = ms
        .iter()
        .map(|&m| (1..=m / 2).fold(Dd::default(), |h, u| h.add(recips[u])))
        .collect();

    // Every term lag k contributes to every m (module doc; t = a - b + c - d with a = x_i,
    // b = x_{i+u}, c = x_{i+m}, d = x_{i+m-u}, each window N - m long).
    let contribute = |k0: usize, acc: &mut [Dd]| {
        let pre = lag_prefixes(&xp, &xl, &xs, n, k0, head_end, tail_start);
        for lane in 0..LANES {
            let k = k0 + lane;
            if k > k_max {
                break;
            }
            for (mi, &m) in ms.iter().enumerate() {
                if m < k {
                    continue;
                }
                let len = n - m;
                let w = |s: usize| pre.at(s + len, lane).sub(pre.at(s, lane));
                let mut add = |coef: Dd, v: Dd| acc[mi] = acc[mi].add(coef.mul(v));
                let h = m / 2;
                if k == 0 {
                    // The four squares a^2 + b^2 + c^2 + d^2.
                    for (u, &r) in recips.iter().enumerate().take(h + 1).skip(1) {
                        add(r, w(0).add(w(u)).add(w(m)).add(w(m - u)));
                    }
                }
                if k >= 1 && k <= h {
                    // -2ab (window from 0) and -2cd (from m - u), lag u = k.
                    add(recips[k].scale(-2.0), w(0).add(w(m - k)));
                }
                if k >= h && k < m {
                    // -2ad (from 0) and -2bc (from u), lag m - u = k.
                    let u = m - k;
                    add(recips[u].scale(-2.0), w(0).add(w(u)));
                }
                if k + 2 <= m && (m - k).is_multiple_of(2) {
                    // +2bd, lag m - 2u = k, from u.
                    let u = (m - k) / 2;
                    add(recips[u].scale(2.0), w(u));
                }
                if k == m {
                    // +2ac, lag m, from 0, for every u.
                    add(harmonic[mi].scale(2.0), w(0));
                }
            }
        }
    };
    let groups = k_max / LANES + 1;
    let run = |first: usize, step: usize| {
        let mut acc = vec![Dd::default(); ms.len()];
        for g in (first..groups).step_by(step) {
            contribute(g * LANES, &mut acc);
        }
        acc
    };
    let acc: Vec<Dd> = if groups >= 4 && n * k_max >= 1 << 20 {
        let (a, b) = std::thread::scope(|scope| {
            let other = scope.spawn(|| run(1, 2));
            (run(0, 2), other.join().expect("Theo1 lag worker panicked"))
        });
        a.iter().zip(&b).map(|(a, b)| a.add(*b)).collect()
    } else {
        run(0, 1)
    };

    // The detrended phase's energy, and the error its double-double rounding (2^-106 of x)
    // contributes to the products.
    let energy_raw: f64 = x.iter().map(|v| v * v).sum();
    let energy_detrended: f64 = xp.iter().map(|v| v * v).sum();
    let energy = energy_detrended + (energy_raw * energy_detrended).sqrt();
    ms.iter()
        .zip(&acc)
        .zip(&harmonic)
        .map(|((&m, s), h)| {
            let sum = s.hi + s.lo;
            let bound = 512.0 * n as f64 * h.hi * U2 * energy;
            if bound <= max_relative_error * sum {
                sum
            } else {
                direct(m)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::theo::theo1_sum;

    /// Standard normal deviates from a fixed-seed LCG (sum of twelve uniforms).
    fn normals(n: usize, seed: u64) -> Vec<f64> {
        let mut state = seed;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| (0..12).map(|_| uniform()).sum::<f64>() - 6.0)
            .collect()
    }

    fn cumsum(v: &[f64]) -> Vec<f64> {
        let mut s = 0.0;
        v.iter()
            .map(|a| {
                s += a;
                s
            })
            .collect()
    }

    /// Phase records of the power-law noises Theo is used on (white PM, white FM, flicker FM as
    /// a sum of AR(1) processes an octave apart, random-walk FM) and white FM on a frequency
    /// offset 10^4 times its noise (a gyro bias, or gravity on an accelerometer).
    fn records(n: usize) -> Vec<(&'static str, Vec<f64>)> {
        let w = normals(n, 7);
        let mut flicker = vec![0.0; n];
        for octave in 0..10 {
            let a = 1.0 - 1.0 / f64::from(1u32 << octave);
            let mut s = 0.0;
            for (f, e) in flicker.iter_mut().zip(normals(n, 100 + octave)) {
                s = a * s + e;
                *f += s * (1.0 - a * a).sqrt();
            }
        }
        let offset: Vec<f64> = w.iter().map(|e| 1e4 + e).collect();
        vec![
            ("white PM", w.clone()),
            ("white FM", cumsum(&w)),
            ("flicker FM", cumsum(&flicker)),
            ("random-walk FM", cumsum(&cumsum(&w))),
            ("white FM on an offset", cumsum(&offset)),
        ]
    }

    /// The shared-lag sums equal the direct double sums at every factor TheoBR uses, to 1e-12
    /// relative, on every record, each within its error bound (a fallback to the direct sum
    /// would show as NaN here); with a bound no sum can meet, every sum is the direct one.
    #[test]
    fn lag_sums_equal_the_direct_double_sums() {
        let n = 3000;
        let ms: Vec<usize> = (0..=97).map(|i| 12 + 4 * i).collect();
        for (name, x) in records(n) {
            let fast = theo1_sums(&x, &ms, |_| f64::NAN);
            for (&m, &got) in ms.iter().zip(&fast) {
                let want = theo1_sum(&x, m);
                assert!(
                    (got / want - 1.0).abs() < 1e-12,
                    "{name} m {m}: lag sum {got} vs direct {want}"
                );
            }
            let direct = theo1_sums_within(&x, &ms, 0.0, |m| theo1_sum(&x, m));
            let want: Vec<f64> = ms.iter().map(|&m| theo1_sum(&x, m)).collect();
            assert_eq!(direct, want, "{name}");
        }
    }

    /// Factors in any order and odd record lengths, the longest factor N - 1 included (windows
    /// one term long), and every m a single pass group covers.
    #[test]
    fn lag_sums_cover_short_and_full_length_windows() {
        let x = cumsum(&normals(41, 3));
        let ms = [40, 2, 10, 24, 38, 4];
        let got = theo1_sums(&x, &ms, |_| f64::NAN);
        for (&m, &g) in ms.iter().zip(&got) {
            let want = theo1_sum(&x, m);
            assert!((g / want - 1.0).abs() < 1e-12, "m {m}: {g} vs {want}");
        }
        assert!(theo1_sums(&x, &[], |_| f64::NAN).is_empty());
    }
}
