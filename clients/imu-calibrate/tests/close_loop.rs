//! Closing the loop (issue 4 item 8): a simulated session recorded through imud's offline path,
//! calibrated by the `imu-calibrate` binary into a calibration file, that file loaded by imud for
//! a second session with a new seed; the corrected stream (`/imu/data`) must then agree with the
//! simulator's truth per static segment to the noise of a segment mean, far below the raw error.
//! The same loop through the model workbench: its ladder finds an effect hidden in the truth and
//! writes the file imud applies.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_analysis::ImuSeries;
use imu_analysis::input::{Source, read_mcap};
use imu_analysis::reference::{Reference, SegmentTruth};
use imu_analysis::segment::{Segment, SegmentKind, SegmentOptions, detect};
use imu_model::{Calibration, EffectKind, NoiseModel, TriadModel, Vec3};

fn config_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config")
        .join(rel)
}

fn truth_model_path() -> PathBuf {
    config_path("models/example-3dm-gx1.toml")
}

/// One offline session of config/scenarios/calibration-session.toml under the example truth model (bias, scale, misalignment,
/// scale nonlinearity, lever arm; gyro g-sensitivity); `calibration` is what imud applies.
/// Returns the recording and the truth file.
fn record(dir: &Path, name: &str, seed: u64, calibration: Option<&Path>) -> (PathBuf, PathBuf) {
    let scenario = config_path("scenarios/calibration-session.toml");
    record_scenario(dir, name, &scenario, &truth_model_path(), seed, calibration)
}

/// One offline session of `scenario` under `truth_model`, imud applying `calibration`.
fn record_scenario(
    dir: &Path,
    name: &str,
    scenario: &Path,
    truth_model: &Path,
    seed: u64,
    calibration: Option<&Path>,
) -> (PathBuf, PathBuf) {
    let s =
        imud::offline::record_session(dir, name, scenario, Some(truth_model), seed, calibration)
            .unwrap();
    (s.recording, s.truth)
}

/// What to fit, written as a model file: the effects (values are starting points) and the noise
/// tables a noise characterisation would give (here the truth model's).
fn write_model(path: &Path, truth: &Calibration) {
    let with = |kinds: &[EffectKind], noise: &Option<NoiseModel>| {
        let mut m = TriadModel::default();
        kinds.iter().for_each(|k| m.add(*k));
        m.noise = noise.clone();
        m
    };
    use EffectKind::*;
    let mut model = Calibration::identity();
    model.accel = with(
        &[Bias, Scale, Misalignment, ScaleNonlinearity],
        &truth.accel.noise,
    );
    model.gyro = with(
        &[Bias, Scale, Misalignment, GSensitivity],
        &truth.gyro.noise,
    );
    model.save(path).unwrap();
}

/// Mean of `x` over a segment's samples.
fn mean(x: &[[f64; 3]], seg: &Segment) -> Vec3 {
    seg.range()
        .map(|i| Vec3::from(x[i]))
        .fold(Vec3::zeros(), |a, v| a + v)
        / seg.n as f64
}

/// RMS over segments of the vector error of segment means, raw and corrected, and the RMS of
/// the expected noise of a segment mean.
struct Errors {
    raw: f64,
    corrected: f64,
    expected: f64,
    n: usize,
}

fn errors(
    segments: &[(&Segment, &SegmentTruth)],
    raw: &[[f64; 3]],
    corrected: &[[f64; 3]],
    truth: impl Fn(&SegmentTruth) -> [f64; 3],
    noise: &NoiseModel,
    recording_s: f64,
) -> Errors {
    let (mut raw_sq, mut cor_sq, mut exp_sq) = (0.0, 0.0, 0.0);
    for (seg, t) in segments {
        let t = Vec3::from(truth(t));
        raw_sq += (mean(raw, seg) - t).norm_squared();
        cor_sq += (mean(corrected, seg) - t).norm_squared();
        let len_s = seg.end_s - seg.start_s;
        exp_sq += (0..3)
            .map(|a| noise.segment_mean_std(a, len_s, recording_s).powi(2))
            .sum::<f64>();
    }
    let n = segments.len() as f64;
    Errors {
        raw: (raw_sq / n).sqrt(),
        corrected: (cor_sq / n).sqrt(),
        expected: (exp_sq / n).sqrt(),
        n: segments.len(),
    }
}

/// The corrected error must be noise (within 3 times the expected noise of a segment mean; a
/// second recording adds the calibration's own error, so about 1.4 times is expected) and at
/// least `min_reduction` times below the raw error.
fn check(what: &str, e: &Errors, min_reduction: f64) {
    eprintln!(
        "{what}: {} segments, RMS error of segment means: raw {:.3e}, corrected {:.3e}, \
         expected noise {:.3e} (corrected / expected {:.2}, raw / corrected {:.0})",
        e.n,
        e.raw,
        e.corrected,
        e.expected,
        e.corrected / e.expected,
        e.raw / e.corrected
    );
    assert!(
        e.corrected <= 3.0 * e.expected,
        "{what}: {:.3e}",
        e.corrected
    );
    assert!(
        e.corrected * min_reduction <= e.raw,
        "{what}: {:.3e}",
        e.corrected
    );
}

#[test]
fn calibration_file_from_imu_calibrate_corrects_a_new_session_in_imud() {
    let dir = tempfile::tempdir().unwrap();
    let truth_model = Calibration::load(&truth_model_path()).unwrap();

    // 1. Calibration session (seed 101), fitted by the real binary into a real file.
    let (recording, truth) = record(dir.path(), "cal", 101, None);
    let model = dir.path().join("model.toml");
    write_model(&model, &truth_model);
    let cal_path = dir.path().join("imu0-calibration.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .arg(&recording)
        .arg("--reference")
        .arg(&truth)
        .arg("--model")
        .arg(&model)
        .arg("-o")
        .arg(&cal_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cal = Calibration::load(&cal_path).unwrap();
    assert!(cal.gyro.has(EffectKind::GSensitivity));

    // 2. A new session (seed 202) with imud applying that file.
    let (recording, truth) = record(dir.path(), "check", 202, Some(&cal_path));
    let rec = imu_rec::recording::read_recording(&recording).unwrap();
    assert_eq!(
        rec.calibrations.len(),
        1,
        "the calibration in force is logged"
    );
    assert_eq!(rec.calibrations[0].id, cal.content_id());
    assert!(
        rec.raw
            .iter()
            .all(|s| s.flags & imu_rec::sample::raw_flags::SATURATED == 0)
    );
    drop(rec);

    let raw: ImuSeries = read_mcap(&recording, Source::Raw, None).unwrap();
    let corrected: ImuSeries = read_mcap(&recording, Source::Corrected, None).unwrap();
    assert_eq!(raw.len(), corrected.len());
    let reference = Reference::Truth(imu_rec::truth::read_truth(&truth).unwrap());
    let segmentation = detect(&raw, &SegmentOptions::default()).unwrap();
    let segment_truth = reference
        .segment_truth(&raw, &segmentation.segments)
        .unwrap();
    let of_kind = |k: SegmentKind| -> Vec<(&Segment, &SegmentTruth)> {
        segmentation
            .segments
            .iter()
            .zip(&segment_truth)
            .filter(|(s, _)| s.kind == k)
            .collect()
    };
    let statics = of_kind(SegmentKind::Static);
    let plateaus = of_kind(SegmentKind::Plateau);
    // 6 positions per sweep (the first one continues the still start), and per rate-table
    // axis: up, the 0 deg/s dwell after the steps, down.
    assert_eq!(statics.len(), 2 * 6 + 3 * 3, "{segmentation:#?}");
    assert_eq!(plateaus.len(), 12, "{segmentation:#?}");
    let recording_s = raw.t_s[raw.len() - 1];
    let accel_noise = truth_model.accel.noise.as_ref().unwrap();
    let gyro_noise = truth_model.gyro.noise.as_ref().unwrap();

    check(
        "accel, static segments (m/s^2)",
        &errors(
            &statics,
            &raw.accel_m_s2,
            &corrected.accel_m_s2,
            |t| t.specific_force_m_s2,
            accel_noise,
            recording_s,
        ),
        10.0,
    );
    check(
        "gyro, static segments (rad/s)",
        &errors(
            &statics,
            &raw.gyro_rad_s,
            &corrected.gyro_rad_s,
            |t| t.angular_rate_rad_s,
            gyro_noise,
            recording_s,
        ),
        10.0,
    );
    // On the rate plateaus the raw error adds scale and misalignment (0.3 % of 80 deg/s is
    // 4e-3 rad/s) to the bias; corrected, it is noise too. The plateaus are 9 s long, so the raw
    // error is only about 18 times the noise of their means: ask for a factor 5.
    check(
        "gyro, rate plateaus (rad/s)",
        &errors(
            &plateaus,
            &raw.gyro_rad_s,
            &corrected.gyro_rad_s,
            |t| t.angular_rate_rad_s,
            gyro_noise,
            recording_s,
        ),
        5.0,
    );
}

/// The model workbench's whole story (issue 6): the simulator hides a gyro g-sensitivity
/// (`config/models/workbench-demo.toml`) under bias, scale and misalignment; imud records the
/// session; the workbench's ladder, started from bias + scale + misalignment, finds the effect
/// and writes a calibration file; imud applies that file to a new session, whose corrected gyro
/// and accel then agree with the truth to the noise of a segment mean. (Without the
/// g-sensitivity the corrected gyro would be off by the hidden 1.2e-4 to 2e-4 (rad/s)/(m/s^2),
/// up to 2e-3 rad/s at 1 g: several times the noise of a segment mean.)
#[test]
fn workbench_ladder_calibration_corrects_a_new_session_in_imud() {
    workbench_ladder_through_imud(imu_proto::DeviceProtocol::Gx1);
}

/// The same loop with the unit speaking MIP: its SI readings (no counts, no GainScales) are
/// what the workbench reads and what imud corrects.
#[test]
fn workbench_ladder_through_imud_over_mip() {
    workbench_ladder_through_imud(imu_proto::DeviceProtocol::Mip);
}

/// The same loop with the unit speaking Xsens: its HR outputs (factory calibration only, as
/// SI floats) are what the workbench reads and imud corrects; its compensated outputs are
/// recorded beside them and play no part.
#[test]
fn workbench_ladder_through_imud_over_xsens() {
    workbench_ladder_through_imud(imu_proto::DeviceProtocol::Xsens);
}

/// The same loop with the unit speaking VectorNav: its uncompensated readings are the raw
/// reading the workbench reads and imud corrects (its compensated ones are recorded beside).
#[test]
fn workbench_ladder_through_imud_over_vectornav() {
    workbench_ladder_through_imud(imu_proto::DeviceProtocol::Vectornav);
}

/// The scenario file for `protocol`: the shipped one, or a copy in `dir` whose device speaks
/// `protocol` (its truth model is passed explicitly, so the copy's place does not matter).
fn scenario_for(dir: &Path, rel: &str, protocol: imu_proto::DeviceProtocol) -> PathBuf {
    let path = config_path(rel);
    if protocol == imu_proto::DeviceProtocol::Gx1 {
        return path;
    }
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        !text.contains("[device]"),
        "{rel} has its own [device] table"
    );
    let copy = dir.join(format!(
        "{protocol}-{}",
        path.file_name().unwrap().to_string_lossy()
    ));
    std::fs::write(
        &copy,
        format!("{text}\n[device]\nprotocol = \"{protocol}\"\n"),
    )
    .unwrap();
    copy
}

fn workbench_ladder_through_imud(protocol: imu_proto::DeviceProtocol) {
    use imu_analysis::workbench::{DiagnoseOptions, Workbench};
    use imu_model::Triad;
    let dir = tempfile::tempdir().unwrap();
    let scenario = scenario_for(dir.path(), "scenarios/workbench-demo.toml", protocol);
    let truth_model_path = config_path("models/workbench-demo.toml");
    let truth_model = Calibration::load(&truth_model_path).unwrap();

    let (recording, truth) =
        record_scenario(dir.path(), "wb", &scenario, &truth_model_path, 301, None);
    let series = read_mcap(&recording, Source::Raw, None).unwrap();
    let reference = Reference::TruthFile(truth);
    let wb = Workbench::new(&series, &reference, DiagnoseOptions::default()).unwrap();
    let base = Calibration::load(&config_path("models/bias-scale-misalignment.toml")).unwrap();
    let ladder = wb.ladder(&base).unwrap();
    let added: Vec<_> = ladder.steps.iter().filter_map(|s| s.added).collect();
    assert_eq!(added, vec![(Triad::Gyro, EffectKind::GSensitivity)]);
    let cal_path = dir.path().join("ladder.toml");
    ladder.calibration.save(&cal_path).unwrap();
    drop(wb);

    let (recording, truth) = record_scenario(
        dir.path(),
        "wb-check",
        &scenario,
        &truth_model_path,
        302,
        Some(&cal_path),
    );
    let raw = read_mcap(&recording, Source::Raw, None).unwrap();
    let corrected = read_mcap(&recording, Source::Corrected, None).unwrap();
    if protocol == imu_proto::DeviceProtocol::Xsens {
        // The unit's own compensated outputs are read by name; the recording's default IMU
        // stream stays imud's corrected one. The simulated unit compensates with the truth
        // model, not the ladder's calibration, so its stream has one sample per raw sample
        // and agrees with imud's to about the calibration's residuals.
        let compensated = read_mcap(
            &recording,
            Source::Corrected,
            Some(imu_rec::recording::DEVICE_COMPENSATED_TOPIC),
        )
        .unwrap();
        assert_eq!(compensated.len(), corrected.len());
        let worst = compensated
            .gyro_rad_s
            .iter()
            .zip(&corrected.gyro_rad_s)
            .flat_map(|(a, b)| (0..3).map(move |k| (a[k] - b[k]).abs()))
            .fold(0.0, f64::max);
        assert!(worst < 5e-3, "{worst} rad/s");
    }
    let reference = Reference::TruthFile(truth);
    let segmentation = detect(&raw, &SegmentOptions::default()).unwrap();
    let segment_truth = reference
        .segment_truth(&raw, &segmentation.segments)
        .unwrap();
    let statics: Vec<(&Segment, &SegmentTruth)> = segmentation
        .segments
        .iter()
        .zip(&segment_truth)
        .filter(|(s, _)| s.kind == SegmentKind::Static)
        .collect();
    assert!(statics.len() >= 20, "{}", statics.len());
    let recording_s = raw.t_s[raw.len() - 1];
    check(
        "workbench: gyro, static segments (rad/s)",
        &errors(
            &statics,
            &raw.gyro_rad_s,
            &corrected.gyro_rad_s,
            |t| t.angular_rate_rad_s,
            truth_model.gyro.noise.as_ref().unwrap(),
            recording_s,
        ),
        5.0,
    );
    check(
        "workbench: accel, static segments (m/s^2)",
        &errors(
            &statics,
            &raw.accel_m_s2,
            &corrected.accel_m_s2,
            |t| t.specific_force_m_s2,
            truth_model.accel.noise.as_ref().unwrap(),
            recording_s,
        ),
        10.0,
    );
}
