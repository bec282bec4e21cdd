//! Validates every Allan-family deviation against the NIST SP 1065 reference values (10-point and
//! 1000-point sets, /work/shared/reference/allan-reference-values.md) to 1e-4 relative, and the
//! streaming OADEV against the batch computation.

use imu_stats::allan::{
    DevCurve, Kind, Options, StreamingOadev, TauSet, deviation, deviation_from_phase,
};

fn at(curve: &DevCurve, m: usize) -> f64 {
    curve
        .points
        .iter()
        .find(|p| p.m == m)
        .unwrap_or_else(|| panic!("no m={m}"))
        .dev
}

fn all_taus() -> Options {
    Options {
        taus: TauSet::All,
        ..Options::default()
    }
}

fn assert_rel(kind: Kind, m: usize, got: f64, want: f64) {
    let rel = (got / want - 1.0).abs();
    assert!(
        rel < 1e-4,
        "{kind:?} m={m}: got {got:.7e}, want {want:.7e} (rel {rel:.1e})"
    );
}

#[test]
fn nist_10_point_set_from_frequency_and_phase() {
    let y = [
        892.0, 809.0, 823.0, 798.0, 671.0, 644.0, 883.0, 903.0, 677.0,
    ];
    let x = [
        0.0, 103.11111, 123.22222, 157.33333, 166.44444, 48.55555, -96.33333, -2.22222, 111.88889,
        0.0,
    ];
    let table = [
        (Kind::Adev, [91.22945, 115.8082]),
        (Kind::Oadev, [91.22945, 85.95287]),
        (Kind::Mdev, [91.22945, 74.78849]),
        (Kind::Totdev, [91.22945, 93.90379]),
        (Kind::Hdev, [70.80608, 116.7980]),
        (Kind::Ohdev, [70.80607, 85.61487]),
        (Kind::Tdev, [52.67135, 86.35831]),
    ];
    for (kind, want) in table {
        let from_y = deviation(kind, &y, 1.0, &all_taus()).unwrap();
        let from_x = deviation_from_phase(kind, &x, 1.0, &all_taus()).unwrap();
        for (m, w) in [(1, want[0]), (2, want[1])] {
            assert_rel(kind, m, at(&from_y, m), w);
            assert_rel(kind, m, at(&from_x, m), w);
        }
    }
}

fn lehmer_1000() -> Vec<f64> {
    let mut n: u64 = 1_234_567_890;
    let mut y = Vec::with_capacity(1000);
    for _ in 0..1000 {
        y.push(n as f64 / 2_147_483_647.0);
        n = (16807 * n) % 2_147_483_647;
    }
    y
}

#[test]
fn lehmer_generator_matches_the_check_values() {
    let mut n: u64 = 1_234_567_890;
    let mut seq = Vec::new();
    for _ in 0..3 {
        n = (16807 * n) % 2_147_483_647;
        seq.push(n);
    }
    assert_eq!(seq, [395_529_916, 1_209_410_747, 633_705_974]);
}

#[test]
fn nist_1000_point_set() {
    let y = lehmer_1000();
    let table = [
        (Kind::Adev, [2.922319e-01, 9.965736e-02, 3.897804e-02]),
        (Kind::Oadev, [2.922319e-01, 9.159953e-02, 3.241343e-02]),
        (Kind::Mdev, [2.922319e-01, 6.172376e-02, 2.170921e-02]),
        (Kind::Totdev, [2.922319e-01, 9.134743e-02, 3.406530e-02]),
        (Kind::Hdev, [2.943883e-01, 1.052754e-01, 3.910860e-02]),
        (Kind::Ohdev, [2.943883e-01, 9.581083e-02, 3.237638e-02]),
        (Kind::Tdev, [1.687202e-01, 3.563623e-01, 1.253382e+00]),
    ];
    let opts = Options {
        taus: TauSet::PerDecade(1),
        ..Options::default()
    };
    for (kind, want) in table {
        let c = deviation(kind, &y, 1.0, &opts).unwrap();
        for (m, w) in [(1, want[0]), (10, want[1]), (100, want[2])] {
            assert_rel(kind, m, at(&c, m), w);
        }
        for p in &c.points {
            assert!(p.dev_lo < p.dev && p.dev < p.dev_hi, "{kind:?} {p:?}");
            assert!(p.edf >= 1.0);
        }
    }
}

#[test]
fn streaming_octave_oadev_equals_batch() {
    // White + random walk, 50k samples at 100 Hz, deterministic.
    let mut state: u64 = 42;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut walk = 0.0;
    let y: Vec<f64> = (0..50_000)
        .map(|_| {
            walk += 1e-3 * uniform();
            0.3 + uniform() + walk
        })
        .collect();
    let batch = deviation(Kind::Oadev, &y, 0.01, &Options::default()).unwrap();
    let mut s = StreamingOadev::new(0.01, 1 << 20);
    for chunk in y.chunks(777) {
        s.extend(chunk);
    }
    assert_eq!(s.n_samples(), y.len());
    let stream = s.curve(0.683, None);
    assert_eq!(stream.points.len(), batch.points.len());
    for (a, b) in stream.points.iter().zip(&batch.points) {
        assert_eq!(a.m, b.m);
        assert_eq!(a.n_terms, b.n_terms);
        assert!(
            (a.dev / b.dev - 1.0).abs() < 1e-9,
            "m={}: {} vs {}",
            a.m,
            a.dev,
            b.dev
        );
        assert!((a.edf / b.edf - 1.0).abs() < 1e-9);
    }
    // Bounded memory: a small m_max still gives the short taus exactly.
    let mut small = StreamingOadev::new(0.01, 64);
    small.extend(&y);
    let c = small.curve(0.683, None);
    assert_eq!(c.points.len(), 7);
    for (a, b) in c.points.iter().zip(&batch.points) {
        assert!((a.dev / b.dev - 1.0).abs() < 1e-9);
    }
}
