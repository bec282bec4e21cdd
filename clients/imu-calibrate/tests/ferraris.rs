//! End-to-end test of the Ferraris procedure (`--plan config/plans/ferraris.toml`): a hand
//! session of six faces and a full turn about each axis, simulated through the daemon's offline
//! pipeline, calibrated with one command and no time windows. Faces and turns are recognised
//! from the data; every parameter of the base model is recovered within 3 standard errors, and
//! the turns give the gyro scale to the precision the sensor's noise allows. And the same
//! session against an independent implementation of Ferraris' closed-form procedure
//! (`tests/python/ferraris_peer.py`, numpy): both calibrations judged on a held-out session.

use std::path::{Path, PathBuf};
use std::process::Command;

use imu_model::nalgebra::{Matrix3, Vector3};
use imu_model::{Calibration, Measured};
use imu_rec::truth::{TruthSample, TruthSegment, read_truth};

/// The truth: the paper's base model on both triads, with the 3DM-GX1-like noise.
const TRUTH: &str = r#"
format = "imud-calibration/1"
[accel.misalignment]
xy = 1.2e-3
xz = -0.8e-3
yx = 0.5e-3
yz = 1.5e-3
zx = -1.1e-3
zy = 0.7e-3
[accel.scale]
value = [1.2e-3, -0.8e-3, 1.5e-3]
[accel.bias]
value = [0.25, -0.18, 0.32]
[accel.noise]
white-density = [1.5e-3, 1.5e-3, 1.8e-3]
quantization-lsb = [2.1e-3, 2.1e-3, 2.1e-3]
[gyro.misalignment]
xy = -0.9e-3
xz = 1.3e-3
yx = 0.6e-3
yz = -1.0e-3
zx = 0.4e-3
zy = 1.1e-3
[gyro.scale]
value = [2.0e-2, -1.5e-2, 3.0e-2]
[gyro.bias]
value = [8.7e-3, -6.1e-3, 1.05e-2]
[gyro.noise]
white-density = [1.0e-3, 1.0e-3, 1.0e-3]
quantization-lsb = [2.6e-4, 2.6e-4, 2.6e-4]
"#;

fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

#[test]
fn a_ferraris_session_calibrates_with_one_command() {
    let dir = tempfile::tempdir().unwrap();
    let truth_model = dir.path().join("truth.toml");
    std::fs::write(&truth_model, TRUTH).unwrap();
    let mut sim = imu_sim::SimOptions::from_files(
        &repo_path("config/scenarios/ferraris.toml"),
        Some(&truth_model),
    )
    .unwrap();
    sim.seed = 5;
    let mut c = imud::config::Config::default();
    c.log.dir = dir.path().join("log");
    c.name = "fer".into();
    let out = imud::offline::record(sim, &c).unwrap();
    // The shipped plan, with the simulator's gravity (standard, whatever its latitude).
    let plan = dir.path().join("ferraris.toml");
    let shipped = std::fs::read_to_string(repo_path("config/plans/ferraris.toml")).unwrap();
    std::fs::write(&plan, format!("{shipped}gravity-m-s2 = 9.80665\n")).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .arg(&out.files[0])
        .arg("--plan")
        .arg(&plan)
        .arg("--truth")
        .arg(&truth_model)
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // ferraris.toml: nine rests (six faces, three of them twice around a turn), three turns.
    assert_eq!(j["recordings"][0]["static_segments"], 9, "{j}");
    assert_eq!(j["recordings"][0]["rate_plateaus"], 3, "{j}");
    let notes = j["fit"]["notes"].to_string();
    assert!(
        notes.contains("6 distinct: +x, +y, +z, -x, -y, -z"),
        "{notes}"
    );
    assert!(notes.contains("3 full turn(s)"), "{notes}");
    let rows = j["truth_comparison"].as_array().unwrap();
    assert_eq!(rows.len(), 24, "{rows:?}");
    for r in rows {
        let name = format!("{} {}", r["triad"], r["name"]);
        let z = r["error_in_se"].as_f64().unwrap_or(f64::NAN);
        assert!(z.abs() < 3.0, "{name}: {r}");
        // One turn fixes a gyro scale to ~1e-3 (the angle's noise over 360 deg); a turn whose
        // mean were weighted by the spread of the rate through it would give ~4e-2.
        if name.contains("gyro") && name.contains("scale") {
            let se = r["std_error"].as_f64().unwrap();
            assert!(se < 3e-3, "{name}: {r}");
        }
    }
}

/// A session recorded through the daemon's offline pipeline: the raw stream (SI through the
/// nominal gains) with, for each sample, its truth record, and the scenario's segments.
struct Session {
    t_s: Vec<f64>,
    accel: Vec<[f64; 3]>,
    gyro: Vec<[f64; 3]>,
    truth: Vec<TruthSample>,
    segments: Vec<TruthSegment>,
}

/// Records `scenario` of `truth_model` with `seed` into `dir/name`.
fn record(dir: &Path, name: &str, scenario: &Path, truth_model: &Path, seed: u64) -> Session {
    let mut sim = imu_sim::SimOptions::from_files(scenario, Some(truth_model)).unwrap();
    sim.seed = seed;
    let truth_path = dir.join(format!("{name}-truth.mcap"));
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join(name);
    c.name = name.into();
    let out = imud::offline::record(sim, &c).unwrap();
    let raw =
        imu_analysis::input::read_mcap(&out.files[0], imu_analysis::Source::Raw, None).unwrap();
    let truth = read_truth(&truth_path).unwrap();
    // Temperature polls have truth records too; the data replies are the samples, in order.
    let data: Vec<TruthSample> = truth
        .samples
        .into_iter()
        .filter(|s| s.command != 0x07)
        .collect();
    assert_eq!(data.len(), raw.len());
    Session {
        t_s: data.iter().map(|s| s.t_s).collect(),
        accel: raw.accel_m_s2,
        gyro: raw.gyro_rad_s,
        truth: data,
        segments: truth.segments,
    }
}

impl Session {
    /// Samples within scenario times `[t0, t1]`.
    fn range(&self, [t0, t1]: [f64; 2]) -> std::ops::Range<usize> {
        self.t_s.partition_point(|&t| t < t0)..self.t_s.partition_point(|&t| t <= t1)
    }

    /// Rests trimmed by 1 s at each end (no settling left) and moves between two rests with
    /// 0.5 s of each: `(rests, moves)` as scenario time windows.
    fn windows(&self) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
        let mut rests = Vec::new();
        let mut moves = Vec::new();
        for s in &self.segments {
            let end = s.end_s.unwrap();
            match s.kind.as_str() {
                "static" => rests.push([s.start_s + 1.0, end - 1.0]),
                "move" => moves.push([s.start_s - 0.5, end + 0.5]),
                other => panic!("unexpected segment kind {other}"),
            }
        }
        (rests, moves)
    }

    /// The text a peer reads: `t ax ay az gx gy gz` per sample.
    fn text(&self) -> String {
        let mut out = String::new();
        for ((t, a), g) in self.t_s.iter().zip(&self.accel).zip(&self.gyro) {
            out.push_str(&format!(
                "{t:.6} {:e} {:e} {:e} {:e} {:e} {:e}\n",
                a[0], a[1], a[2], g[0], g[1], g[2]
            ));
        }
        out
    }
}

/// A calibration as the held-out comparison uses it: measured (accel, gyro) to true.
trait Correct {
    fn correct(&self, accel: Vector3<f64>, gyro: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>);
}

impl Correct for Calibration {
    fn correct(&self, accel: Vector3<f64>, gyro: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let m = Measured {
            accel_m_s2: accel,
            gyro_rad_s: gyro,
            mag_gauss: Vector3::zeros(),
        };
        let c = Calibration::correct(self, &m, 25.0, 0.0, Vector3::zeros());
        (c.accel_m_s2, c.gyro_rad_s)
    }
}

/// The peer's result: `u = S x + b` for each triad.
struct Peer {
    accel: (Matrix3<f64>, Vector3<f64>),
    gyro: (Matrix3<f64>, Vector3<f64>),
}

impl Peer {
    fn from_json(j: &serde_json::Value) -> Self {
        let triad = |t: &serde_json::Value| {
            let s: Vec<Vec<f64>> = serde_json::from_value(t["s"].clone()).unwrap();
            let b: Vec<f64> = serde_json::from_value(t["b"].clone()).unwrap();
            (
                Matrix3::from_fn(|r, c| s[r][c]),
                Vector3::from_column_slice(&b),
            )
        };
        Peer {
            accel: triad(&j["accel"]),
            gyro: triad(&j["gyro"]),
        }
    }
}

impl Correct for Peer {
    fn correct(&self, accel: Vector3<f64>, gyro: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let inv = |(s, b): &(Matrix3<f64>, Vector3<f64>), u: Vector3<f64>| {
            s.try_inverse().unwrap() * (u - b)
        };
        (inv(&self.accel, accel), inv(&self.gyro, gyro))
    }
}

/// On the held-out session: per rest, the corrected accel's error against the true specific
/// force (m/s^2); per move, the corrected gyro's integrated angle's error against the true
/// one (deg). Both calibrations are affine, so the mean and the integral are corrected whole.
fn held_out_errors(s: &Session, cal: &dyn Correct) -> (Vec<f64>, Vec<f64>) {
    let dt = 1.0 / 100.0;
    let mean = |v: &[[f64; 3]]| {
        v.iter()
            .fold(Vector3::zeros(), |a, x| a + Vector3::from(*x))
            / v.len() as f64
    };
    let (rests, moves) = s.windows();
    let rest_errors = rests
        .iter()
        .map(|&w| {
            let r = s.range(w);
            let (a, _) = cal.correct(mean(&s.accel[r.clone()]), mean(&s.gyro[r.clone()]));
            let f: Vec<[f64; 3]> = s.truth[r].iter().map(|x| x.specific_force_m_s2).collect();
            (a - mean(&f)).norm()
        })
        .collect();
    let move_errors = moves
        .iter()
        .map(|&w| {
            let r = s.range(w);
            let n = r.len() as f64;
            let (_, g) = cal.correct(mean(&s.accel[r.clone()]), mean(&s.gyro[r.clone()]));
            let w_true: Vec<[f64; 3]> = s.truth[r].iter().map(|x| x.angular_rate_rad_s).collect();
            ((g - mean(&w_true)) * n * dt).norm().to_degrees()
        })
        .collect();
    (rest_errors, move_errors)
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Held-out poses and moves: tilted rests (no face), turns of 90-270 deg about the sensor
/// axes and the moves between the rests about whatever axes they need.
const HELD_OUT: &str = r#"
name = "held-out"
rate-hz = 100.0
latitude-deg = 40.0
[[segment]]
kind = "static"
orientation = { roll-deg = 30.0, pitch-deg = 20.0, yaw-deg = 10.0 }
duration-s = 6.0
[[segment]]
kind = "rotate"
axis = "x"
angle-deg = 180.0
duration-s = 3.0
[[segment]]
kind = "static"
duration-s = 6.0
[[segment]]
kind = "rotate"
axis = "y"
angle-deg = -270.0
duration-s = 4.0
[[segment]]
kind = "static"
duration-s = 6.0
[[segment]]
kind = "static"
orientation = { roll-deg = 135.0, pitch-deg = -40.0, yaw-deg = 70.0 }
duration-s = 6.0
[[segment]]
kind = "rotate"
axis = "z"
angle-deg = 90.0
duration-s = 2.0
[[segment]]
kind = "static"
duration-s = 6.0
[[segment]]
kind = "static"
orientation = { roll-deg = -60.0, pitch-deg = 65.0, yaw-deg = -120.0 }
duration-s = 6.0
"#;

/// Runs the peer on `session`; None when python3 or numpy is missing (exit 77), which fails
/// under CI (`IMUD_REQUIRE_PEERS`).
fn run_peer(dir: &Path, session: &Session, gravity_m_s2: f64) -> Option<serde_json::Value> {
    let data = dir.join("peer-data.txt");
    std::fs::write(&data, session.text()).unwrap();
    let (faces, turns) = session.windows();
    // The peer is told which windows are turns, as the procedure's operator knows: the three
    // 360-degree rotations, not the moves between faces.
    let turns: Vec<[f64; 2]> = session
        .segments
        .iter()
        .filter(|s| s.kind == "move")
        .zip(&turns)
        .filter(|(s, _)| s.label.contains("rotate 360") || s.label.contains("rotate -360"))
        .map(|(_, w)| *w)
        .collect();
    assert_eq!(turns.len(), 3);
    let windows = serde_json::json!({
        "gravity_m_s2": gravity_m_s2,
        "faces": faces,
        "turns": turns,
    });
    let windows_path = dir.join("peer-windows.json");
    std::fs::write(&windows_path, windows.to_string()).unwrap();
    let script = repo_path("tests/python/ferraris_peer.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(&data)
        .arg(&windows_path)
        .output();
    match out {
        Ok(o) if o.status.success() => Some(serde_json::from_slice(&o.stdout).unwrap()),
        Ok(o) if o.status.code() == Some(77) || o.status.code() == Some(127) => {
            assert!(
                std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
                "IMUD_REQUIRE_PEERS is set but python3 with numpy is missing"
            );
            eprintln!("skipping the Ferraris peer: python3 with numpy is missing");
            None
        }
        Ok(o) => panic!("{}", String::from_utf8_lossy(&o.stderr)),
        Err(e) => {
            assert!(
                std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
                "IMUD_REQUIRE_PEERS is set but python3 cannot run: {e}"
            );
            eprintln!("skipping the Ferraris peer: {e}");
            None
        }
    }
}

/// Our Ferraris plan and the independent closed-form implementation on the same simulated
/// session, judged on a held-out session of the same unit (tilted rests, turns and moves about
/// every axis, its own noise): both close to the truth, and close to each other.
#[test]
fn ferraris_agrees_with_an_independent_implementation_on_held_out_data() {
    const G: f64 = 9.80665;
    let dir = tempfile::tempdir().unwrap();
    let truth_model = dir.path().join("truth.toml");
    std::fs::write(&truth_model, TRUTH).unwrap();
    let session = record(
        dir.path(),
        "fer",
        &repo_path("config/scenarios/ferraris.toml"),
        &truth_model,
        9,
    );
    let held_out_scenario = dir.path().join("held-out.toml");
    std::fs::write(&held_out_scenario, HELD_OUT).unwrap();
    let held_out = record(dir.path(), "held", &held_out_scenario, &truth_model, 10);

    let Some(peer) = run_peer(dir.path(), &session, G) else {
        return;
    };
    assert_eq!(
        peer["faces"],
        serde_json::json!(["+x", "+y", "+z", "-x", "-y", "-z"])
    );
    let peer = Peer::from_json(&peer);

    let plan = dir.path().join("ferraris.toml");
    let shipped = std::fs::read_to_string(repo_path("config/plans/ferraris.toml")).unwrap();
    std::fs::write(&plan, format!("{shipped}gravity-m-s2 = {G}\n")).unwrap();
    let ours_path = dir.path().join("ours.toml");
    let rec = std::fs::read_dir(dir.path().join("fer"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let o = Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
        .arg(&rec)
        .arg("--plan")
        .arg(&plan)
        .arg("-o")
        .arg(&ours_path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ours = Calibration::load(&ours_path).unwrap();
    let truth = Calibration::load(&truth_model).unwrap();

    let report = |name: &str, cal: &dyn Correct| {
        let (rests, moves) = held_out_errors(&held_out, cal);
        eprintln!(
            "{name:>5}: rests RMS {:.3e} m/s^2 (max {:.3e}), moves RMS {:.4} deg (max {:.4})",
            rms(&rests),
            rests.iter().copied().fold(0.0, f64::max),
            rms(&moves),
            moves.iter().copied().fold(0.0, f64::max)
        );
        (rests, moves)
    };
    let (truth_rests, truth_moves) = report("truth", &truth);
    let (our_rests, our_moves) = report("ours", &ours);
    let (peer_rests, peer_moves) = report("peer", &peer);
    assert_eq!(our_rests.len(), 6);
    assert_eq!(our_moves.len(), 5);
    // Against the truth. The truth model itself leaves the noise of each window: ~1.5e-3
    // m/s^2 on a 4 s rest (white 1.5e-3 m/s^2/sqrt(Hz) over 4 s, 2.1e-3 quantisation steps),
    // ~0.2 deg on a 3-5 s move (1e-3 rad/s/sqrt(Hz) integrated, three axes). A calibration
    // from a 1.5-minute session adds its own estimation error (biases ~1e-3 m/s^2, gyro
    // scale ~1e-3 of 90-270 deg, a few tenths of a degree).
    assert!(rms(&truth_rests) < 3e-3 && rms(&truth_moves) < 0.4);
    for (name, rests, moves) in [
        ("ours", &our_rests, &our_moves),
        ("peer", &peer_rests, &peer_moves),
    ] {
        assert!(rms(rests) < 5e-3, "{name}: rests {rests:?}");
        assert!(rms(moves) < 0.6, "{name}: moves {moves:?}");
    }
    // Against each other, window by window: the same data corrected by both. They estimate
    // the same model from the same session and differ only in how they weigh it (our fit
    // weights the rests and turns by their noise and removes Earth's vertical rate; Ferraris
    // pools the six faces equally): observed ~5e-4 m/s^2 and ~0.05 deg, bounded at three
    // times that.
    let (rests, moves) = held_out.windows();
    let dt = 0.01;
    let mean = |v: &[[f64; 3]]| {
        v.iter()
            .fold(Vector3::zeros(), |a, x| a + Vector3::from(*x))
            / v.len() as f64
    };
    let both = |w: [f64; 2]| {
        let r = held_out.range(w);
        let (a, g) = (
            mean(&held_out.accel[r.clone()]),
            mean(&held_out.gyro[r.clone()]),
        );
        (
            Correct::correct(&ours, a, g),
            Correct::correct(&peer, a, g),
            r.len() as f64 * dt,
        )
    };
    for w in rests {
        let ((a_ours, _), (a_peer, _), _) = both(w);
        let d = (a_ours - a_peer).norm();
        eprintln!("rest {w:?}: ours - peer {d:.3e} m/s^2");
        assert!(d < 1.5e-3, "rest {w:?}: {a_ours} vs {a_peer}");
    }
    for w in moves {
        let ((_, g_ours), (_, g_peer), t) = both(w);
        let d_deg = ((g_ours - g_peer) * t).norm().to_degrees();
        eprintln!("move {w:?}: ours - peer {d_deg:.4} deg");
        assert!(d_deg < 0.2, "move {w:?}: {d_deg} deg");
    }
}

/// The part a lab would label truth segment `s` with: its face, its turn, or `move`.
fn part_label(s: &TruthSegment) -> String {
    let signed = |v: [f64; 3]| {
        let a = (0..3)
            .max_by(|&i, &j| v[i].abs().total_cmp(&v[j].abs()))
            .unwrap();
        (["x", "y", "z"][a], if v[a] < 0.0 { "-" } else { "+" })
    };
    match s.kind.as_str() {
        "static" => {
            let (axis, sign) = signed(s.gravity_dir_sensor.map(|g| -g));
            format!("face-{axis}{sign}")
        }
        _ if s.label.contains("rotate") => format!("turn-{}", signed(s.axis_sensor.unwrap()).0),
        _ => "move".into(),
    }
}

/// A labelled Ferraris session as text (`t,ax,ay,az,gx,gy,gz,part`, the `part` column found by
/// its header): one command, faces and turns from the labels, every parameter within 3
/// standard errors; a turn labelled about the wrong axis is refused, naming the part.
#[test]
fn a_labelled_ferraris_session_in_text_calibrates_with_one_command() {
    const G: f64 = 9.80665;
    let dir = tempfile::tempdir().unwrap();
    let truth_model = dir.path().join("truth.toml");
    std::fs::write(&truth_model, TRUTH).unwrap();
    let session = record(
        dir.path(),
        "fer",
        &repo_path("config/scenarios/ferraris.toml"),
        &truth_model,
        12,
    );
    let plan = dir.path().join("ferraris.toml");
    let shipped = std::fs::read_to_string(repo_path("config/plans/ferraris.toml")).unwrap();
    std::fs::write(
        &plan,
        format!("{shipped}gravity-m-s2 = {G}\ntemp-c = 25.0\n"),
    )
    .unwrap();
    let write = |name: &str, label: &dyn Fn(&TruthSegment) -> String| {
        let mut text = String::from("t,ax,ay,az,gx,gy,gz,part\n");
        for (line, t) in session.text().lines().zip(&session.truth) {
            let seg = &session.segments[t.segment as usize];
            text.push_str(&format!("{},{}\n", line.replace(' ', ","), label(seg)));
        }
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let run = |csv: &Path| {
        Command::new(env!("CARGO_BIN_EXE_imu-calibrate"))
            .arg(csv)
            .arg("--plan")
            .arg(&plan)
            .arg("--truth")
            .arg(&truth_model)
            .arg("--json")
            .output()
            .unwrap()
    };
    let o = run(&write("labelled.csv", &part_label));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["recordings"][0]["static_segments"], 9, "{j}");
    assert_eq!(j["recordings"][0]["rate_plateaus"], 3, "{j}");
    let rows = j["truth_comparison"].as_array().unwrap();
    assert_eq!(rows.len(), 24, "{rows:?}");
    for r in rows {
        let z = r["error_in_se"].as_f64().unwrap_or(f64::NAN);
        assert!(z.abs() < 3.0, "{r}");
    }

    let wrong = |s: &TruthSegment| {
        if s.label.contains("rotate 360 deg about +z") {
            "turn-x".into()
        } else {
            part_label(s)
        }
    };
    let o = run(&write("mislabelled.csv", &wrong));
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("part `turn-x`") && err.contains("mostly about +z"),
        "{err}"
    );
}
