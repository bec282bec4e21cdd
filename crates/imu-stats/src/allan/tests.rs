//! Tests of the Allan family against direct sums, every kernel path and the streaming form.

use pulp::{Arch, Simd};

use super::kernels::*;
use super::passes::*;
use super::*;

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
            for got in [scalar[k], best[k], oadev_sums(&x, &[m])[0]] {
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

/// MDEV of a rate with a large offset (an accelerometer's 1 g): the m-sample sums of second
/// differences are formed from small phase differences, so the result equals the direct sum to
/// rounding. Forming them as differences of the running sum of the phase (which grows like
/// g N^2 / 2, here 2e11) left errors of 4e-6 to 4e-4 of the deviation on such a record (issue 24).
#[test]
fn mdev_of_a_large_offset_equals_the_direct_sum() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let y: Vec<f64> = (0..200_000)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            9.81 + 1e-3 * ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
        })
        .collect();
    let x = phase_from_rate(&y, 1.0);
    let direct = |m: usize| -> f64 {
        let s: Vec<f64> = (0..x.len() - 2 * m)
            .map(|i| (x[i + 2 * m] - x[i + m]) - (x[i + m] - x[i]))
            .collect();
        let terms = x.len() - 3 * m + 1;
        let sum: f64 = (0..terms)
            .map(|j| s[j..j + m].iter().sum::<f64>().powi(2))
            .sum();
        (sum / (2.0 * (m * m * m * m) as f64 * terms as f64)).sqrt()
    };
    let opts = Options {
        taus: TauSet::Factors(vec![1, 7, 64]),
        ..Options::default()
    };
    let curve = deviation_from_phase(Kind::Mdev, &x, 1.0, &opts).expect("mdev");
    for p in &curve.points {
        let want = direct(p.m);
        assert!(
            (p.dev / want - 1.0).abs() < 1e-9,
            "m {}: {:e} vs {want:e}",
            p.m,
            p.dev
        );
    }
}

/// A random walk of `len` points (xorshift steps in -0.5..0.5).
fn walk(len: usize, mut state: u64) -> Vec<f64> {
    let mut w = 0.0;
    (0..len)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            w += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            w
        })
        .collect()
}

/// The ADEV/HDEV, OHDEV and MDEV passes (tau groups, per-tau leftovers, block edges, vector
/// tails, MDEV's lanes and their parts) on both the scalar and the best SIMD instruction set,
/// against plain loops: the strided and overlapping sums term by term, MDEV by the serial
/// recurrence.
#[test]
fn fused_passes_equal_the_plain_sums() {
    let x = walk(2 * BLOCK + 1237, 0x2545_f491_4f6c_dd1d);
    let n = x.len();
    let plain = |d: usize, m: usize, stride: usize| -> f64 {
        (0..n - d * m)
            .step_by(stride)
            .map(|i| {
                let t = if d == 2 {
                    passes_second(&x, i, m)
                } else {
                    passes_third(&x, i, m)
                };
                t * t
            })
            .sum()
    };
    let close = |got: f64, want: f64, what: &str, m: usize| {
        assert!(
            (got / want - 1.0).abs() < 1e-12,
            "{what} m {m}: {got} vs {want}"
        );
    };
    let max_m = (n - 1) / 3;
    for ms in [
        TauSet::Octave.factors(max_m),
        TauSet::PerDecade(7).factors(max_m),
        vec![
            1, 2, 3, 5, 6, 12, 24, 25, 50, 100, 101, 202, 404, 808, 1616, 3232, max_m,
        ],
        vec![max_m],
        vec![max_m - 3],
    ] {
        let scalar = pulp::Scalar::new();
        let arch = Arch::new();
        let adev = [
            scalar.vectorize(NonOverlappingPass::<2> {
                x: &x,
                ms: &ms,
                range: 0..n - 2,
            }),
            arch.dispatch(NonOverlappingPass::<2> {
                x: &x,
                ms: &ms,
                range: 0..n - 2,
            }),
            non_overlapping_sums::<2>(&x, &ms),
        ];
        let hdev = [
            scalar.vectorize(NonOverlappingPass::<3> {
                x: &x,
                ms: &ms,
                range: 0..n - 3,
            }),
            arch.dispatch(NonOverlappingPass::<3> {
                x: &x,
                ms: &ms,
                range: 0..n - 3,
            }),
            non_overlapping_sums::<3>(&x, &ms),
        ];
        let ohdev = [
            scalar.vectorize(OverlappingThirdPass {
                x: &x,
                ms: &ms,
                range: 0..n - 3 * ms[0],
            }),
            arch.dispatch(OverlappingThirdPass {
                x: &x,
                ms: &ms,
                range: 0..n - 3 * ms[0],
            }),
            overlapping_third_sums(&x, &ms),
        ];
        let long: Vec<usize> = ms
            .iter()
            .copied()
            .filter(|&m| n - 3 * m + 1 >= 4 * LANES)
            .collect();
        let mdev = [
            scalar.vectorize(ModifiedPass {
                x: &x,
                ms: &long,
                part: 0,
                parts: 1,
                fuse: false,
            }),
            arch.dispatch(ModifiedPass {
                x: &x,
                ms: &long,
                part: 0,
                parts: 1,
                fuse: true,
            }),
            {
                let pass = |part| {
                    arch.dispatch(ModifiedPass {
                        x: &x,
                        ms: &long,
                        part,
                        parts: 3,
                        fuse: true,
                    })
                };
                let (a, b, c) = (pass(0), pass(1), pass(2));
                (0..long.len()).map(|k| a[k] + b[k] + c[k]).collect()
            },
        ];
        // The fused loop (AVX2 CPUs) computes every v_j with the scratch path's operations:
        // the sums are bit-identical, whichever rows the fused loop leaves to the scratch
        // path (the part's last row, the rows whose loads would pass the end of x).
        let scratch = arch.dispatch(ModifiedPass {
            x: &x,
            ms: &long,
            part: 0,
            parts: 1,
            fuse: false,
        });
        assert_eq!(mdev[0], scratch, "scalar vs SIMD scratch path");
        assert_eq!(mdev[1], scratch, "fused vs scratch path");
        for (k, &m) in ms.iter().enumerate() {
            for got in &adev {
                close(got[k], plain(2, m, m), "adev", m);
            }
            for got in &hdev {
                close(got[k], plain(3, m, m), "hdev", m);
            }
            for got in &ohdev {
                close(got[k], plain(3, m, 1), "ohdev", m);
            }
            let want = modified_sum_plain(&x, m);
            close(modified_sums(&x, &ms)[k], want, "mdev", m);
            if let Some(j) = long.iter().position(|&l| l == m) {
                for got in &mdev {
                    close(got[j], want, "mdev lanes", m);
                }
            }
        }
    }
}

fn passes_second(x: &[f64], i: usize, m: usize) -> f64 {
    x[i + 2 * m] - 2.0 * x[i + m] + x[i]
}

fn passes_third(x: &[f64], i: usize, m: usize) -> f64 {
    x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i]
}

/// On a long series the two-thread passes (chunks of i; MDEV's halves of every tau) give the
/// single-threaded sums.
#[test]
fn long_series_fused_passes_equal_one_thread() {
    let x = walk(PARALLEL_MIN_PHASE_POINTS + 4321, 0x9e37_79b9_7f4a_7c15);
    let n = x.len();
    let arch = Arch::new();
    let close = |a: &[f64], b: &[f64], what: &str| {
        assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(b) {
            assert!((p / q - 1.0).abs() < 1e-12, "{what}: {p} vs {q}");
        }
    };
    let ms = TauSet::Octave.factors(Kind::Hdev.max_m(n));
    close(
        &non_overlapping_sums::<2>(&x, &ms),
        &arch.dispatch(NonOverlappingPass::<2> {
            x: &x,
            ms: &ms,
            range: 0..n - 2,
        }),
        "adev",
    );
    close(
        &non_overlapping_sums::<3>(&x, &ms),
        &arch.dispatch(NonOverlappingPass::<3> {
            x: &x,
            ms: &ms,
            range: 0..n - 3,
        }),
        "hdev",
    );
    close(
        &overlapping_third_sums(&x, &ms),
        &arch.dispatch(OverlappingThirdPass {
            x: &x,
            ms: &ms,
            range: 0..n - 3,
        }),
        "ohdev",
    );
    let plain: Vec<f64> = ms.iter().map(|&m| modified_sum_plain(&x, m)).collect();
    close(&modified_sums(&x, &ms), &plain, "mdev");
}
