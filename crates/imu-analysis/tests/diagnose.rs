//! Hidden-effect tests of the model workbench: the simulator's truth model hides one physical
//! effect (or two, or one outside the library) on top of bias + scale + misalignment, a session
//! is recorded through imud's offline pipeline, and the workbench must (a) call the base model
//! inconsistent with the noise floor, (b) rank the hidden effect first at p < 0.001, (c) after
//! adding it, bring the residual RMS to within 20 % of the noise floor and stop the ladder.
//! Negative controls: nothing hidden (also with bias-instability/random-walk dominated noise)
//! must not produce a significant effect in more than one of 20 seeds; a periodic disturbance
//! outside the library must not be blamed on a library effect.

use imu_analysis::ImuSeries;
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::reference::Reference;
use imu_analysis::segment::SegmentKind;
use imu_analysis::workbench::{
    DiagnoseOptions, Finding, Ladder, NotObservable, Separation, TriadDiagnosis, Workbench,
};
use imu_model::{Calibration, EffectKind, Triad, TriadModel};
use imu_rec::truth::read_truth;

/// The truth every test starts from: bias, scale and misalignment on both triads (the base
/// model's effects), with the example 3DM-GX1's coloured noise.
const BASE_TRUTH: &str = include_str!("data/diagnose-base-truth.toml");

/// Index table about x, then about y: 2 x 12 positions at 30 degrees, 20 s each (paper 3.1.2):
/// the shipped workbench demo's motion (its own truth model is overridden by each test's).
const INDEX_TABLE: &str = include_str!("../../../config/scenarios/workbench-demo.toml");

/// Rate table (paper 3.2.3): each axis vertical in turn, steps of both signs, 10 s plateaus.
const RATE_TABLE: &str = r#"
name = "rate-table-diagnose"
rate-hz = 100.0
latitude-deg = 40.0

[[segment]]
kind = "static"
orientation = { z = "up", x = "north" }
duration-s = 20.0
[[segment]]
kind = "rate-steps"
axis = "z"
rates-deg-s = [30, 60, 90, 120, 0, -30, -60, -90, -120, 0]
dwell-s = 10.0
accel-deg-s2 = 60.0

[[segment]]
kind = "static"
orientation = { x = "up", y = "north" }
move-s = 5.0
duration-s = 20.0
[[segment]]
kind = "rate-steps"
axis = "x"
rates-deg-s = [30, 60, 90, 120, 0, -30, -60, -90, -120, 0]
dwell-s = 10.0
accel-deg-s2 = 60.0

[[segment]]
kind = "static"
orientation = { y = "up", z = "north" }
move-s = 5.0
duration-s = 20.0
[[segment]]
kind = "rate-steps"
axis = "y"
rates-deg-s = [30, 60, 90, 120, 0, -30, -60, -90, -120, 0]
dwell-s = 10.0
accel-deg-s2 = 60.0
"#;

struct Run {
    _dir: tempfile::TempDir,
    series: ImuSeries,
    reference: Reference,
}

/// Records `scenario` with the truth `BASE_TRUTH` + `hidden` through imud's offline path.
fn record(scenario: &str, hidden: &str, seed: u64) -> Run {
    record_with_truth(scenario, &format!("{BASE_TRUTH}\n{hidden}"), seed)
}

/// Records `scenario` with the truth model text `truth` through imud's offline path.
fn record_with_truth(scenario: &str, truth: &str, seed: u64) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let session =
        imud::offline::record_session_text(dir.path(), "t", scenario, Some(truth), seed, None)
            .unwrap();
    let series = read_mcap(&session.recording, Source::Raw, None).unwrap();
    let reference = Reference::Truth(read_truth(&session.truth).unwrap());
    Run {
        _dir: dir,
        series,
        reference,
    }
}

fn base_model() -> TriadModel {
    TriadModel::with_effects(&TriadModel::PAPER_BASE)
}

fn base_calibration() -> Calibration {
    let mut c = Calibration::identity();
    c.accel = base_model();
    c.gyro = base_model();
    c
}

fn show(d: &TriadDiagnosis) {
    eprintln!("{}", d.verdict);
    for c in d.candidates.iter().take(4) {
        eprintln!(
            "  {:<20} dp {:>2} F {:>9.2} p {:>9.2e} dAIC {:>9.1} share {:>5} sig {} claimed {}",
            c.effect.id(),
            c.new_params,
            c.f,
            c.p_value,
            c.delta_aic,
            c.share_of_excess_cell(),
            c.significant,
            c.claimed
        );
    }
    for a in &d.ambiguities {
        eprintln!("  ambiguous {:?} r {:.3}", a.effects, a.correlation);
    }
}

fn show_ladder(l: &Ladder) {
    for d in &l.final_diagnoses {
        for kind in [SegmentKind::Static, SegmentKind::Plateau] {
            let z: Vec<f64> = d
                .segments
                .iter()
                .filter(|s| s.kind == kind)
                .flat_map(|s| s.z)
                .collect();
            let rms = (z.iter().map(|v| v * v).sum::<f64>() / z.len().max(1) as f64).sqrt();
            eprintln!(
                "  final {} {kind:?}: {} values, rms z {rms:.2}",
                d.triad,
                z.len()
            );
        }
    }
    for s in &l.steps {
        eprintln!(
            "  step {:?}: accel rms {:.2e} {:.2e} {:.2e} floor {:.2e} {:.2e} {:.2e} p {:.1e} | gyro rms {:.2e} {:.2e} {:.2e} floor {:.2e} {:.2e} {:.2e} p {:.1e}",
            s.added,
            s.accel.residual_rms[0],
            s.accel.residual_rms[1],
            s.accel.residual_rms[2],
            s.accel.noise_floor_rms[0],
            s.accel.noise_floor_rms[1],
            s.accel.noise_floor_rms[2],
            s.accel.p_value,
            s.gyro.residual_rms[0],
            s.gyro.residual_rms[1],
            s.gyro.residual_rms[2],
            s.gyro.noise_floor_rms[0],
            s.gyro.noise_floor_rms[1],
            s.gyro.noise_floor_rms[2],
            s.gyro.p_value,
        );
        eprintln!(
            "    drift-consistent accel {} gyro {}",
            s.accel.consistent_with_drift, s.gyro.consistent_with_drift
        );
    }
}

/// The issue's criteria (a)-(c) for one hidden effect on one triad.
///
/// `max_ratio` is the issue's 1.2: the residual RMS over the noise floor with the bias wander
/// the residuals show (both axes' expectations from the fit's own residual maker).
fn assert_found(
    scenario: &str,
    hidden: &str,
    triad: Triad,
    effect: EffectKind,
    seed: u64,
    max_ratio: f64,
) {
    let run = record(scenario, hidden, seed);
    let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
    assert_found_by(&wb, triad, effect, max_ratio);
}

/// (a)-(c) on an open workbench; returns the ladder.
fn assert_found_by(wb: &Workbench, triad: Triad, effect: EffectKind, max_ratio: f64) -> Ladder {
    let d = wb.diagnose(triad, &base_model()).unwrap();
    show(&d);
    // (a) the base model is inconsistent with the noise floor.
    assert!(!d.consistent, "base model called consistent: {}", d.verdict);
    // (b) the hidden effect ranks first, significant at p < 0.001, and is claimed.
    let top = &d.candidates[0];
    assert_eq!(top.effect, effect, "{}", d.verdict);
    assert!(top.p_value < 1e-3 && top.claimed, "{}", d.verdict);
    // ... and it holds on new data: refitted without the held-out segments (poses), it lowers
    // their error too.
    let h = top
        .held_out
        .as_ref()
        .expect("a claim carries its held-out check");
    let sq = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>();
    eprintln!("{}", h.summary(h.rms_unit(triad)));
    assert!(h.confirmed, "{}", d.verdict);
    assert!(
        sq(&h.held_out_rms_after) < sq(&h.held_out_rms_before),
        "{}",
        h.summary(h.rms_unit(triad))
    );
    // (c) the ladder adds it, the residual falls to within 20 % of the floor, and it stops.
    let ladder = wb.ladder(&base_calibration()).unwrap();
    show_ladder(&ladder);
    let added: Vec<_> = ladder.steps.iter().filter_map(|s| s.added).collect();
    assert_eq!(added, vec![(triad, effect)], "ladder added {added:?}");
    let last = ladder.steps.last().unwrap();
    let s = if triad == Triad::Gyro {
        &last.gyro
    } else {
        &last.accel
    };
    let ratio = rms_ratio(s);
    let strict = {
        let sq = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>();
        (sq(&s.residual_rms) / sq(&s.noise_floor_rms)).sqrt()
    };
    eprintln!("RATIO {effect}: {ratio:.3} strict {strict:.3}");
    assert!(
        ratio <= max_ratio,
        "residual RMS {ratio:.2}x the noise floor"
    );
    ladder
}

/// Residual RMS over the noise floor RMS, all three axes together.
fn rms_ratio(s: &imu_analysis::workbench::StepSummary) -> f64 {
    let sq = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>();
    (sq(&s.residual_rms) / sq(&s.noise_floor_with_drift_rms)).sqrt()
}

#[test]
fn finds_hidden_gyro_g_sensitivity() {
    assert_found(
        INDEX_TABLE,
        "[gyro.g-sensitivity]\nmatrix = [[1.5e-4, 0.0, 0.5e-4], [0.0, -1.2e-4, 0.0], [0.6e-4, 0.0, 2.0e-4]]\n",
        Triad::Gyro,
        EffectKind::GSensitivity,
        11,
        1.2,
    );
}

#[test]
fn finds_hidden_accel_scale_nonlinearity() {
    assert_found(
        INDEX_TABLE,
        "[accel.scale-nonlinearity]\nquadratic = [3.0e-4, -2.0e-4, 4.0e-4]\n",
        Triad::Accel,
        EffectKind::ScaleNonlinearity,
        12,
        1.2,
    );
}

#[test]
fn finds_hidden_gyro_scale_nonlinearity() {
    assert_found(
        RATE_TABLE,
        "[gyro.scale-nonlinearity]\nquadratic = [2.0e-3, -1.5e-3, 2.5e-3]\n",
        Triad::Gyro,
        EffectKind::ScaleNonlinearity,
        13,
        1.2,
    );
}

#[test]
fn finds_hidden_gyro_asymmetric_scale() {
    assert_found(
        RATE_TABLE,
        "[gyro.asymmetric-scale]\nvalue = [2.0e-3, -1.5e-3, 2.5e-3]\n",
        Triad::Gyro,
        EffectKind::AsymmetricScale,
        14,
        1.2,
    );
}

#[test]
fn finds_hidden_accel_lever_arm_on_the_rate_table() {
    assert_found(
        RATE_TABLE,
        "[accel.lever-arm]\noffset-m = [0.02, -0.015, 0.01]\n",
        Triad::Accel,
        EffectKind::LeverArm,
        15,
        1.2,
    );
}

/// Static positions through a temperature cycle after warm-up: temperature changes without
/// the time since power-on, so a temperature coefficient is identifiable.
fn temperature_cycle_positions() -> String {
    let mut s = String::from(
        r#"
name = "temperature-cycle"
rate-hz = 100.0
latitude-deg = 40.0
power-on-before-s = 3600.0
temperature = { kind = "cycle", mean-c = 30.0, amplitude-c = 8.0, period-s = 600.0 }
"#,
    );
    let orientations = [
        r#"{ z = "up", x = "north" }"#,
        r#"{ z = "down", x = "north" }"#,
        r#"{ x = "up", y = "north" }"#,
        r#"{ x = "down", y = "north" }"#,
        r#"{ y = "up", z = "north" }"#,
        r#"{ y = "down", z = "north" }"#,
    ];
    for i in 0..36 {
        s.push_str(&format!(
            "\n[[segment]]\nkind = \"static\"\norientation = {}\nduration-s = 20.0\nmove-s = 3.0\n",
            orientations[i % orientations.len()]
        ));
    }
    s
}

/// Static positions right after power-on at a constant temperature: only the time since
/// power-on changes, so a warm-up transient is identifiable.
fn warmup_positions() -> String {
    temperature_cycle_positions()
        .replace("power-on-before-s = 3600.0\n", "")
        .replace(
            r#"temperature = { kind = "cycle", mean-c = 30.0, amplitude-c = 8.0, period-s = 600.0 }"#,
            r#"temperature = { kind = "constant", value-c = 25.0 }"#,
        )
}

#[test]
fn finds_hidden_gyro_temperature_bias_in_a_temperature_cycle() {
    assert_found(
        &temperature_cycle_positions(),
        "[gyro.temp-bias]\nt0-c = 25.0\ncoefficients = [[1.5e-4, -1.0e-4, 2.0e-4]]\n",
        Triad::Gyro,
        EffectKind::TempBias,
        16,
        1.2,
    );
}

#[test]
fn finds_hidden_gyro_warmup_transient() {
    assert_found(
        &warmup_positions(),
        "[gyro.warmup]\namplitude = [6.0e-3, -4.0e-3, 5.0e-3]\ntau-s = 180.0\n",
        Triad::Gyro,
        EffectKind::Warmup,
        17,
        1.2,
    );
}

/// A warm-up recording where the temperature rises monotonically with time since power-on: a
/// temperature coefficient and a warm-up transient explain the same thing. The workbench must
/// say so and name the recording that separates them, not pick one silently.
#[test]
fn monotonic_warmup_cannot_separate_temperature_bias_from_warmup() {
    let scenario = temperature_cycle_positions()
        .replace("power-on-before-s = 3600.0\n", "")
        .replace(
            r#"temperature = { kind = "cycle", mean-c = 30.0, amplitude-c = 8.0, period-s = 600.0 }"#,
            r#"temperature = { kind = "warmup", ambient-c = 22.0, operating-c = 38.0, tau-s = 200.0 }"#,
        );
    let run = record(
        &scenario,
        "[gyro.temp-bias]\nt0-c = 25.0\ncoefficients = [[3.0e-4, -2.0e-4, 2.5e-4]]\n",
        18,
    );
    let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
    let d = wb.diagnose(Triad::Gyro, &base_model()).unwrap();
    show(&d);
    assert!(!d.consistent);
    let pair = d
        .ambiguities
        .iter()
        .find(|a| {
            a.effects.contains(&EffectKind::TempBias) && a.effects.contains(&EffectKind::Warmup)
        })
        .unwrap_or_else(|| panic!("no ambiguity reported: {}", d.verdict));
    assert!(pair.correlation.abs() > 0.9);
    assert_eq!(pair.separating_recording, Separation::TemperatureCycle);
    assert!(!d.candidates[0].claimed, "{}", d.verdict);
    assert!(
        matches!(&d.verdict.finding, Finding::Ambiguous(Some(a)) if a.effects == pair.effects),
        "{}",
        d.verdict
    );
    assert_eq!(d.verdict.code(), "ambiguous");
}

/// Nothing hidden: over 20 seeds no effect may be significant at p < 0.001 in more than one
/// run, for the example 3DM-GX1 noise and for a sensor whose noise is dominated by bias
/// instability and random walk.
fn negative_control(name: &str, truth: &str) {
    negative_control_by(name, 100..120, |seed| {
        let run = record_with_truth(INDEX_TABLE, truth, seed);
        let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
        diagnose_both(&wb)
    });
}

fn diagnose_both(wb: &Workbench) -> [TriadDiagnosis; 2] {
    [Triad::Accel, Triad::Gyro].map(|t| wb.diagnose(t, &base_model()).unwrap())
}

/// Runs `diagnose(seed)` over `seeds`: asserts that at most one run has a significant
/// candidate; returns how many verdicts were inconsistent even with the bias wander allowed.
fn negative_control_by(
    name: &str,
    seeds: std::ops::Range<u64>,
    diagnose: impl Fn(u64) -> [TriadDiagnosis; 2],
) -> usize {
    let mut flagged = Vec::new();
    let mut inconsistent = 0;
    for seed in seeds {
        for d in diagnose(seed) {
            inconsistent += usize::from(!d.consistent_with_drift);
            for c in d.candidates.iter().filter(|c| c.significant) {
                flagged.push(format!(
                    "seed {seed} {} {} p {:.1e}",
                    d.triad, c.effect, c.p_value
                ));
            }
        }
    }
    eprintln!("{name}: {flagged:?}, {inconsistent} verdicts inconsistent with drift");
    let runs: std::collections::BTreeSet<&str> = flagged
        .iter()
        .map(|f| f.split(' ').nth(1).unwrap_or(""))
        .collect();
    assert!(
        runs.len() <= 1,
        "{name}: effects claimed in {} runs: {flagged:?}",
        runs.len()
    );
    inconsistent
}

#[test]
fn negative_control_example_noise_over_20_seeds() {
    negative_control("example", BASE_TRUTH);
}

#[test]
fn negative_control_bias_instability_and_random_walk_dominated_noise_over_20_seeds() {
    let coloured = BASE_TRUTH
        .replace(
            "white-density = [1.0e-3, 1.0e-3, 1.0e-3]",
            "white-density = [1.0e-4, 1.0e-4, 1.0e-4]",
        )
        .replace(
            "bias-instability = [2.4e-4, 2.4e-4, 2.4e-4]",
            "bias-instability = [1.0e-3, 1.0e-3, 1.0e-3]",
        )
        .replace(
            "random-walk = [1.0e-5, 1.0e-5, 1.0e-5]",
            "random-walk = [5.0e-5, 5.0e-5, 5.0e-5]",
        );
    assert_ne!(coloured, BASE_TRUTH);
    negative_control("coloured", &coloured);
}

/// A periodic disturbance is outside the library: no library effect may be claimed, and the
/// report must say that structure remains and show it.
#[test]
fn periodic_disturbance_outside_the_library_is_not_blamed_on_an_effect() {
    let scenario = format!(
        "{INDEX_TABLE}\n[[disturbance]]\ntriad = \"gyro\"\namplitude = [0.0, 0.0, 6.0e-3]\nfrequency-hz = 2.3\n"
    );
    let run = record(&scenario, "", 19);
    let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
    let d = wb.diagnose(Triad::Gyro, &base_model()).unwrap();
    show(&d);
    assert!(d.candidates.iter().all(|c| !c.claimed), "{}", d.verdict);
    let line = d
        .spectral_lines
        .iter()
        .find(|l| l.axis == 2)
        .unwrap_or_else(|| panic!("no spectral line: {}", d.verdict));
    assert!(
        (line.frequency_hz - 2.3).abs() < 0.1,
        "{}",
        line.frequency_hz
    );
    assert!(
        (line.amplitude / 6.0e-3 - 1.0).abs() < 0.3,
        "amplitude {:.2e}",
        line.amplitude
    );
    assert!(!d.consistent);
    assert!(
        d.verdict.codes().contains(&"periodic_component"),
        "{}",
        d.verdict
    );
    assert!(d.verdict.lines.iter().any(|l| l.axis == 2));
    // The same recording without the disturbance has no line.
    let clean = record(INDEX_TABLE, "", 19);
    let wb = Workbench::new(&clean.series, &clean.reference, DiagnoseOptions::default()).unwrap();
    let d = wb.diagnose(Triad::Gyro, &base_model()).unwrap();
    assert!(d.spectral_lines.is_empty(), "{:?}", d.spectral_lines);
}

/// Two effects hidden at once (one per triad) are both found by the ladder.
#[test]
fn ladder_finds_two_hidden_effects() {
    let run = record(
        INDEX_TABLE,
        "[gyro.g-sensitivity]\nmatrix = [[1.5e-4, 0.0, 0.5e-4], [0.0, -1.2e-4, 0.0], [0.6e-4, 0.0, 2.0e-4]]\n\
         [accel.scale-nonlinearity]\nquadratic = [3.0e-4, -2.0e-4, 4.0e-4]\n",
        20,
    );
    let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
    let ladder = wb.ladder(&base_calibration()).unwrap();
    show_ladder(&ladder);
    let added: Vec<_> = ladder.steps.iter().filter_map(|s| s.added).collect();
    // Both hidden effects are found, and nothing else.
    assert_eq!(added.len(), 2, "{added:?}");
    assert!(
        added.contains(&(Triad::Accel, EffectKind::ScaleNonlinearity)),
        "{added:?}"
    );
    assert!(
        added.contains(&(Triad::Gyro, EffectKind::GSensitivity)),
        "{added:?}"
    );
    assert!(ladder.calibration.gyro.has(EffectKind::GSensitivity));
    assert!(ladder.calibration.accel.has(EffectKind::ScaleNonlinearity));
}

#[test]
fn report_sections_show_the_verdict_the_ladder_and_charts() {
    use imu_analysis::render::html::{
        diagnose_section, escape, ladder_section, page, verdict_section,
    };
    let run = record(
        INDEX_TABLE,
        "[gyro.g-sensitivity]\nmatrix = [[1.5e-4, 0.0, 0.5e-4], [0.0, -1.2e-4, 0.0], [0.6e-4, 0.0, 2.0e-4]]\n",
        11,
    );
    let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
    let gyro = wb.diagnose(Triad::Gyro, &base_model()).unwrap();
    let accel = wb.diagnose(Triad::Accel, &base_model()).unwrap();
    let signals = wb.signal_values(Triad::Gyro);
    assert!(signals.iter().all(|(_, v)| v.len() == gyro.segments.len()));
    let verdict = verdict_section(&[&accel, &gyro]);
    assert!(
        verdict.html.contains(&escape(&gyro.verdict.to_string())),
        "{}",
        verdict.html
    );
    assert!(verdict.html.contains("NOT consistent"), "{}", verdict.html);
    let section = diagnose_section(&gyro, &signals);
    assert!(section.html.contains(&escape(&gyro.verdict.to_string())));
    assert!(section.html.contains("<svg"));
    assert!(section.html.contains("residual vs"), "no correlate chart");
    // Every candidate signal has its chart: temperature and time since power-on among them.
    for name in [
        "temperature",
        "time since power-on",
        "specific force x",
        "rotation rate",
    ] {
        assert!(
            section.html.contains(&format!("residual vs {name}")),
            "no chart against {name}"
        );
    }
    assert!(section.html.contains("Allan deviation"));
    assert!(section.html.contains("g-sensitivity"));
    assert!(section.html.contains("Model change"));
    let ladder = wb.ladder(&base_calibration()).unwrap();
    let ls = ladder_section(&ladder.steps);
    assert!(ls.html.contains("<table") && ls.html.contains("gyro g-sensitivity"));
    let html = page("workbench", &[verdict, ls, section]);
    assert!(html.contains("The ladder") && html.contains("<svg"));
    assert!(!html.contains("<script") && !html.contains("src=\""));
}

// ------------------------------------------------------------------------------ reference-free

/// Hand-held poses (config/scenarios/multi-pose.toml: 36 random still poses, 10 s each, at 40
/// degrees latitude): no reference at all.
const MULTI_POSE: &str = include_str!("../../../config/scenarios/multi-pose.toml");

/// Records the multi-pose scenario with `BASE_TRUTH` + `hidden` and opens a reference-free
/// workbench on it (latitude given, as a user would).
fn reference_free_run(hidden: &str, seed: u64) -> Run {
    record(MULTI_POSE, hidden, seed)
}

fn reference_free_workbench(run: &Run) -> Workbench<'_> {
    Workbench::reference_free(&run.series, None, Some(40.0), DiagnoseOptions::default()).unwrap()
}

/// (a)-(c) of the hidden-effect tests without a reference: the base model is inconsistent,
/// the hidden effect ranks first and is claimed at p < 0.001, the ladder adds exactly it and
/// the residual falls to within 20 % of the noise floor.
fn assert_found_reference_free(hidden: &str, triad: Triad, effect: EffectKind, seed: u64) {
    let run = reference_free_run(hidden, seed);
    let ladder = assert_found_by(&reference_free_workbench(&run), triad, effect, 1.2);
    eprintln!("ladder notes: {:#?}", ladder.notes);
    // The final calibration is loadable and carries the added effect.
    let text = ladder.calibration.to_toml_string();
    let back = Calibration::from_toml_str(&text, "ladder.toml").unwrap();
    assert!(back.triad(triad).has(effect), "{text}");
    assert!(
        back.gyro.has(EffectKind::Scale),
        "gyro gains fitted from the moves: {text}"
    );
}

#[test]
fn reference_free_finds_hidden_accel_scale_nonlinearity() {
    assert_found_reference_free(
        "[accel.scale-nonlinearity]\nquadratic = [3.0e-4, -2.0e-4, 4.0e-4]\n",
        Triad::Accel,
        EffectKind::ScaleNonlinearity,
        31,
    );
}

#[test]
fn reference_free_finds_hidden_gyro_g_sensitivity() {
    assert_found_reference_free(
        "[gyro.g-sensitivity]\nmatrix = [[1.5e-4, 0.0, 0.5e-4], [0.0, -1.2e-4, 0.0], [0.6e-4, 0.0, 2.0e-4]]\n",
        Triad::Gyro,
        EffectKind::GSensitivity,
        32,
    );
}

/// Nothing hidden, no reference: over 20 seeds no effect is significant at p < 0.001 in more
/// than one run, and the base model is called consistent (allowing the bias wander) in most.
#[test]
fn reference_free_negative_control_over_20_seeds() {
    let inconsistent = negative_control_by("reference-free", 200..220, |seed| {
        let run = reference_free_run("", seed);
        diagnose_both(&reference_free_workbench(&run))
    });
    // At alpha = 0.001 over 40 verdicts, more than 2 rejections means a wrong floor.
    assert!(
        inconsistent <= 2,
        "{inconsistent} of 40 verdicts inconsistent"
    );
}

/// An index table turns nothing: a lever arm is excited only by Earth's rate, and its fit
/// would give hundreds of kilometres. The candidate is reported as not measurable here, with
/// the reason, instead of with such a value.
#[test]
fn a_barely_excited_candidate_says_so_instead_of_giving_absurd_values() {
    let run = record(INDEX_TABLE, "", 23);
    let wb = Workbench::new(&run.series, &run.reference, DiagnoseOptions::default()).unwrap();
    let d = wb.diagnose(Triad::Accel, &base_model()).unwrap();
    let c = d
        .candidates
        .iter()
        .find(|c| c.effect == EffectKind::LeverArm)
        .unwrap();
    assert_eq!(c.new_params, 0, "{}", c.explanation);
    assert!(c.params.is_empty());
    assert!(
        c.not_observable
            .iter()
            .any(|w| matches!(w, NotObservable::LeverArmBarelyExcited { .. })),
        "{:?}",
        c.not_observable
    );
    assert_eq!(c.explanation.code(), "not_observable");
}

/// Reference-free gyro gains: an asymmetric scale hidden in the truth shows in the rotations
/// integrated over the moves between hand-held poses (both signs on every axis); the base
/// gains (scale, misalignment) are inconsistent with the moves, the asymmetry is claimed, and
/// the ladder adds it and writes it into the calibration.
#[test]
fn reference_free_finds_hidden_gyro_asymmetric_scale_in_the_moves() {
    let run = reference_free_run(
        "[gyro.asymmetric-scale]\nvalue = [6.0e-3, -5.0e-3, 7.0e-3]\n",
        33,
    );
    let wb = reference_free_workbench(&run);
    let d = wb.diagnose(Triad::Gyro, &base_model()).unwrap();
    show(&d);
    let m = d.moves.as_ref().unwrap();
    assert!(!m.consistent, "{}", d.verdict);
    assert!(!d.consistent, "{}", d.verdict);
    let c = d.candidates.iter().find(|c| c.claimed).unwrap();
    assert_eq!(c.effect, EffectKind::AsymmetricScale, "{}", d.verdict);
    assert!(c.p_value < 1e-3, "{}", d.verdict);
    // Held against moves its fit did not see, the asymmetry lowers their direction error too.
    let h = c
        .held_out
        .as_ref()
        .expect("a claim carries its held-out check");
    eprintln!("{}", h.summary(h.rms_unit(Triad::Gyro)));
    assert!(h.confirmed, "{}", d.verdict);
    assert!(
        h.held_out_rms_after[0] < h.held_out_rms_before[0],
        "{}",
        d.verdict
    );
    let ladder = wb.ladder(&base_calibration()).unwrap();
    show_ladder(&ladder);
    let added: Vec<_> = ladder.steps.iter().filter_map(|s| s.added).collect();
    assert_eq!(added, vec![(Triad::Gyro, EffectKind::AsymmetricScale)]);
    let last = ladder.steps.last().unwrap().gyro.moves.clone().unwrap();
    eprintln!(
        "moves after: {:.3e} rad vs {:.3e} expected, p {:.2e}",
        last.residual_rms_rad, last.expected_rms_rad, last.p_value
    );
    assert!(last.consistent, "{last:?}");
    assert!(
        last.residual_rms_rad < 1.2 * last.expected_rms_rad,
        "{last:?}"
    );
    let cal = &ladder.calibration;
    assert!(cal.gyro.has(EffectKind::AsymmetricScale), "{cal:?}");
    // Within 3 standard errors of the truth (gauge: the accel frame; the asymmetry is a
    // per-axis gain, unaffected by the small rotation between the frames).
    let names = cal.gyro.param_names(Triad::Gyro);
    let se = cal.gyro.std_errors();
    for (a, truth) in [6.0e-3, -5.0e-3, 7.0e-3].iter().enumerate() {
        let name = format!("asymmetric-scale.{}", ["x", "y", "z"][a]);
        let i = names.iter().position(|n| *n == name).unwrap();
        let (v, s) = (cal.gyro.params()[i], se[i].unwrap());
        eprintln!("{name}: {v:.3e} +/- {s:.1e} (truth {truth:.1e})");
        assert!(
            (v - truth).abs() < 3.0 * s,
            "{name}: {v:.3e} +/- {s:.1e} vs {truth}"
        );
    }
}
