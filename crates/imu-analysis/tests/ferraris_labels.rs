//! A labelled Ferraris session: the shipped Ferraris scenario through the daemon's offline
//! pipeline, each sample labelled with its part as a lab would write them (`face-z+`, `+x`,
//! `turn-z`, `rot_x`, `move`). The procedure takes its faces and turns from the labels and finds
//! what recognition finds; a label that disagrees with the data is an error naming the part.

use std::path::Path;

use imu_analysis::ImuSeries;
use imu_analysis::input::{Labels, Source, read_mcap};
use imu_analysis::reference::ferraris::Ferraris;
use imu_analysis::segment::{SegmentKind, SegmentOptions, Segmentation};
use imu_rec::truth::{TruthSegment, read_truth};

const PLAN: &str = "format = \"imud-plan/1\"\nprocedure = \"ferraris\"\nlatitude-deg = 40.0\n";

/// `+x` etc. for signed axis vector `v` (a unit axis).
fn signed(v: [f64; 3]) -> String {
    let a = (0..3)
        .max_by(|&i, &j| v[i].abs().total_cmp(&v[j].abs()))
        .unwrap();
    format!(
        "{}{}",
        if v[a] < 0.0 { "-" } else { "+" },
        ["x", "y", "z"][a]
    )
}

/// The label a lab would give truth segment `s`: its face (written several ways), its turn, or
/// `move`.
fn label_of(s: &TruthSegment) -> String {
    match s.kind.as_str() {
        "static" => {
            // At rest the accelerometer reads up: the face is the axis against gravity.
            let up = signed(s.gravity_dir_sensor.map(|g| -g));
            match s.index % 3 {
                0 => up,
                1 => format!("face-{}{}", &up[1..], &up[..1]),
                _ => format!("pos {up}"),
            }
        }
        _ if s.label.contains("rotate") => {
            let axis = signed(s.axis_sensor.unwrap());
            if s.index.is_multiple_of(2) {
                format!("turn-{}", &axis[1..])
            } else {
                format!("rot_{}", &axis[1..])
            }
        }
        _ => "move".into(),
    }
}

/// The session and its truth segments, each sample labelled by `label`.
fn labelled_session(dir: &Path) -> (ImuSeries, Vec<TruthSegment>, Vec<u32>) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut sim = imu_sim::SimOptions::from_files(
        &repo.join("config/scenarios/ferraris.toml"),
        Some(&repo.join("config/models/example-3dm-gx1.toml")),
    )
    .unwrap();
    sim.seed = 3;
    let truth_path = dir.join("truth.mcap");
    sim.truth_out = Some(truth_path.clone());
    let mut c = imud::config::Config::default();
    c.log.dir = dir.join("log");
    c.name = "fer".into();
    let out = imud::offline::record(sim, &c).unwrap();
    let series = read_mcap(&out.files[0], Source::Raw, None).unwrap();
    let truth = read_truth(&truth_path).unwrap();
    let per_sample: Vec<u32> = truth
        .samples
        .iter()
        .filter(|s| s.command != 0x07)
        .map(|s| s.segment)
        .collect();
    assert_eq!(per_sample.len(), series.len());
    (series, truth.segments, per_sample)
}

fn with_labels(
    series: &ImuSeries,
    segments: &[TruthSegment],
    per_sample: &[u32],
    name: impl Fn(&TruthSegment) -> String,
) -> ImuSeries {
    let mut labels = Labels::default();
    for &i in per_sample {
        labels.push(&name(&segments[i as usize]));
    }
    ImuSeries {
        labels: Some(labels),
        ..series.clone()
    }
}

/// The faces (signed up axes) and turn axes of a segmentation, in time order.
fn faces_and_turns(series: &ImuSeries, seg: &Segmentation) -> (Vec<String>, Vec<String>) {
    let (mut faces, mut turns) = (Vec::new(), Vec::new());
    for s in &seg.segments {
        match s.kind {
            SegmentKind::Static => faces.push(signed(s.mean_accel_m_s2)),
            SegmentKind::Plateau => {
                let r = s.range();
                let angle: [f64; 3] = std::array::from_fn(|a| {
                    series.gyro_rad_s[r.clone()]
                        .iter()
                        .map(|w| w[a])
                        .sum::<f64>()
                });
                turns.push(signed(angle));
            }
        }
    }
    (faces, turns)
}

#[test]
fn labelled_faces_and_turns_are_taken_from_the_labels_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let (series, segments, per_sample) = labelled_session(dir.path());
    let plan = Ferraris::from_toml_str(PLAN, "ferraris.toml")
        .unwrap()
        .unwrap();
    let opts = SegmentOptions::default();
    let recognised = plan.segmentation(&series, &opts).unwrap();
    let labelled_series = with_labels(&series, &segments, &per_sample, label_of);
    let labelled = plan.segmentation(&labelled_series, &opts).unwrap();
    // The same nine rests on six faces and three turns, the turns exactly the labelled parts.
    let (faces, turns) = faces_and_turns(&series, &labelled);
    assert_eq!(
        faces_and_turns(&series, &recognised),
        (faces.clone(), turns.clone())
    );
    assert_eq!(faces.len(), 9);
    assert_eq!(turns, ["+z", "-x", "+y"]);
    let rotations: Vec<&TruthSegment> = segments
        .iter()
        .filter(|s| s.label.contains("rotate"))
        .collect();
    for (s, r) in labelled
        .segments
        .iter()
        .filter(|s| s.kind == SegmentKind::Plateau)
        .zip(rotations)
    {
        let first = per_sample.iter().position(|&i| i == r.index).unwrap();
        let last = per_sample.iter().rposition(|&i| i == r.index).unwrap();
        assert_eq!(s.range(), first..last + 1);
    }

    // A face labelled wrongly: the part is named, with what gravity says.
    let wrong_face = with_labels(&series, &segments, &per_sample, |s| {
        if s.index == 0 {
            "face-x+".into()
        } else {
            label_of(s)
        }
    });
    let e = plan
        .segmentation(&wrong_face, &opts)
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("ferraris.toml: part `face-x+` (0.0-")
            && e.contains("gravity says the face is +z"),
        "{e}"
    );
    // A turn about the wrong axis, and in the wrong sense.
    for (name, says) in [("turn-x", "about +z"), ("turn-z-", "about +z")] {
        let wrong_turn = with_labels(&series, &segments, &per_sample, |s| {
            if s.label.contains("rotate 360 deg about +z") {
                name.into()
            } else {
                label_of(s)
            }
        });
        let e = plan
            .segmentation(&wrong_turn, &opts)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("part `{name}`")) && e.contains(says),
            "{e}"
        );
    }
    // Labels that name no face or turn leave recognition in charge.
    let plain = with_labels(&series, &segments, &per_sample, |s| {
        format!("step {}", s.index)
    });
    assert_eq!(
        faces_and_turns(&series, &plan.segmentation(&plain, &opts).unwrap()),
        faces_and_turns(&series, &recognised)
    );
}
