//! The two procedures: a fit against references (plans, logs, truth; one or several recordings)
//! and the reference-free fit of hand-held poses, each writing the calibration and its report.

use super::*;

pub(super) fn run_reference_free(cli: &Cli, recording: &Recording, hashing: Hashing) -> Result<()> {
    let series = &recording.series;
    let duration_s = series.t_s[series.len() - 1] - series.t_s[0];
    let base = options(cli, duration_s)?;
    let opts = ReferenceFreeOptions {
        accel: base.accel,
        gyro: base.gyro,
        gravity_m_s2: cli.gravity_m_s2,
        latitude_deg: cli.latitude_deg,
        accel_bias_drift_m_s2: base.accel_bias_drift_m_s2,
        gyro_bias_drift_rad_s: base.gyro_bias_drift_rad_s,
        ..ReferenceFreeOptions::default()
    };
    let mut fit = calibrate_reference_free(series, &opts)
        .with_context(|| format!("calibrating {} (reference-free)", recording.name))?;
    // The gauge is a convention, not a limit of the data: listed in the notes, not as held.
    let held: Vec<String> = [&fit.accel, &fit.gyro]
        .iter()
        .flat_map(|f| {
            f.unobservable
                .iter()
                .filter(|u| u.reason != imu_analysis::calibrate::NotFitted::Gauge)
                .map(|u| format!("{} {}", f.triad, u.name))
        })
        .collect();
    stamp(&mut fit.calibration, (hashing, &[series]), &fit.notes, held)?;
    if let Some(path) = &cli.output {
        fit.calibration
            .save(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let truth_rows = reference_free_truth_rows(cli, &fit)?;
    report_reference_free(cli, recording, &fit, truth_rows)
}

/// The reference-free fit against `--truth` (in the accel frame the fit uses), if given.
fn reference_free_truth_rows(cli: &Cli, fit: &ReferenceFreeFit) -> Result<Option<Vec<TruthRow>>> {
    let Some(path) = &cli.truth else {
        return Ok(None);
    };
    let t = Calibration::load(path).with_context(|| format!("loading truth {}", path.display()))?;
    let t = in_accel_frame(&t);
    let mut rows = Vec::new();
    for (f, m) in [(&fit.accel, &t.accel), (&fit.gyro, &t.gyro)] {
        rows.extend(compare(
            f.triad,
            &f.names,
            &f.units,
            &f.params,
            &f.std_errors,
            m,
        ));
    }
    Ok(Some(rows))
}

/// Prints the reference-free fit as JSON or as tables.
fn report_reference_free(
    cli: &Cli,
    recording: &Recording,
    fit: &ReferenceFreeFit,
    truth_rows: Option<Vec<TruthRow>>,
) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if cli.json {
        let j = JsonOutReferenceFree {
            recording: recording.name.clone(),
            procedure: "reference-free",
            output: cli.output.as_ref().map(|p| p.display().to_string()),
            fit,
            truth_comparison: truth_rows,
            inputs_unfinished: unfinished_json(&recording.series).into_iter().collect(),
            input: &recording.series.input,
        };
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        print_reference_free(&mut out, fit, truth_rows.as_deref())?;
        if let Some(p) = &cli.output {
            writeln!(out, "\nwrote {}", p.display())?;
        }
    }
    out.flush()?;
    Ok(())
}

pub(super) fn run_reference(
    cli: &Cli,
    loaded: &[(Recording, Reference)],
    refs: &[ReferenceArg],
    (accel_turn_on_bias_m_s2, gyro_turn_on_bias_rad_s): (Option<[f64; 3]>, Option<[f64; 3]>),
    hashing: Hashing,
) -> Result<()> {
    let duration_s = loaded
        .iter()
        .map(|(r, _)| r.series.t_s[r.series.len() - 1] - r.series.t_s[0])
        .fold(0.0, f64::max);
    let mut opts = options(cli, duration_s)?;
    opts.accel_turn_on_bias_m_s2 = accel_turn_on_bias_m_s2;
    opts.gyro_turn_on_bias_rad_s = gyro_turn_on_bias_rad_s;
    let pairs: Vec<_> = loaded.iter().map(|(s, r)| (&s.series, r)).collect();
    let names = loaded
        .iter()
        .map(|(r, _)| r.name.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    let mut fit =
        calibrate_recordings(&pairs, &opts).with_context(|| format!("calibrating {names}"))?;

    describe_reference_fit(&mut fit, loaded);
    let held: Vec<String> = fit
        .accel
        .unobservable
        .iter()
        .map(|u| format!("accel {}", u.name))
        .chain(
            fit.gyro
                .unobservable
                .iter()
                .map(|u| format!("gyro {}", u.name)),
        )
        .collect();
    let cal = &mut fit.calibration;
    let series: Vec<_> = loaded.iter().map(|(r, _)| &r.series).collect();
    stamp(cal, (hashing, &series), &fit.notes, held)?;
    if let Some(path) = &cli.output {
        cal.save(path)
            .with_context(|| format!("writing {}", path.display()))?;
    }

    let truth_rows = match &cli.truth {
        Some(path) => {
            let t = Calibration::load(path)
                .with_context(|| format!("loading truth {}", path.display()))?;
            let mut rows = truth_rows(&fit.accel, &t.accel);
            rows.extend(truth_rows(&fit.gyro, &t.gyro));
            Some(rows)
        }
        None => None,
    };
    report_reference(cli, loaded, refs, &fit, truth_rows)
}

/// The calibration's description and procedure: what was fitted, from how many segments of how
/// many recordings, against which references.
fn describe_reference_fit(fit: &mut CalibrationFit, loaded: &[(Recording, Reference)]) {
    let several = loaded.len() > 1;
    let (n_static, n_plateau) = (
        fit.count(SegmentKind::Static),
        fit.count(SegmentKind::Plateau),
    );
    let cal = &mut fit.calibration;
    cal.description = Some(format!(
        "accel and gyro fitted from {n_static} static segments and {n_plateau} rate plateaus{}",
        if several {
            format!(" of {} recordings", loaded.len())
        } else {
            String::new()
        }
    ));
    let described = if several {
        loaded
            .iter()
            .enumerate()
            .map(|(k, (_, r))| format!("recording {}: {}", k + 1, r.describe()))
            .collect::<Vec<_>>()
            .join("; ")
    } else {
        loaded[0].1.describe()
    };
    cal.provenance.procedure = Some(format!(
        "static/plateau segmentation; weighted Levenberg-Marquardt fit of segment means to the \
         true input from the {described} (Aslan & Saranli 3.1.2, 3.2.2, 3.2.3)"
    ));
}

/// Prints the fit against references as JSON or as tables.
fn report_reference(
    cli: &Cli,
    loaded: &[(Recording, Reference)],
    refs: &[ReferenceArg],
    fit: &CalibrationFit,
    truth_rows: Option<Vec<TruthRow>>,
) -> Result<()> {
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if cli.json {
        let j = reference_json(cli, loaded, refs, fit, truth_rows);
        serde_json::to_writer_pretty(&mut out, &j)?;
        writeln!(out)?;
    } else {
        if loaded.len() <= 1 {
            writeln!(out, "reference: {}", loaded[0].1.describe())?;
        }
        print_tables(&mut out, fit, truth_rows.as_deref())?;
        if let Some(p) = &cli.output {
            writeln!(out, "\nwrote {}", p.display())?;
        }
    }
    out.flush()?;
    Ok(())
}

/// The JSON document of a fit against references: per recording what it contributed, and for
/// one recording its reference also at the top level.
fn reference_json<'a>(
    cli: &Cli,
    loaded: &[(Recording, Reference)],
    refs: &[ReferenceArg],
    fit: &'a CalibrationFit,
    truth_rows: Option<Vec<TruthRow>>,
) -> JsonOut<'a> {
    let recordings: Vec<JsonRecording> = fit
        .recordings
        .iter()
        .zip(refs)
        .zip(loaded)
        .map(|((r, arg), (recording, _))| JsonRecording {
            recording: recording.name.clone(),
            input: recording.series.input.clone(),
            reference: arg.path().display().to_string(),
            reference_description: r.reference.clone(),
            static_segments: r.segmentation.count(SegmentKind::Static),
            rate_plateaus: r.segmentation.count(SegmentKind::Plateau),
            skipped_segments: r.segmentation.skipped.len(),
            accel_points: r.accel_points.len(),
            gyro_points: r.gyro_points.len(),
        })
        .collect();
    let (recording, reference, reference_description) = match recordings.as_slice() {
        [r] => (
            Some(r.recording.clone()),
            Some(r.reference.clone()),
            Some(r.reference_description.clone()),
        ),
        _ => (None, None, None),
    };
    JsonOut {
        recording,
        reference,
        reference_description,
        recordings,
        output: cli.output.as_ref().map(|p| p.display().to_string()),
        fit,
        truth_comparison: truth_rows,
        inputs_unfinished: loaded
            .iter()
            .filter_map(|(r, _)| unfinished_json(&r.series))
            .collect(),
    }
}

/// The JSON of a recording read without its footer: the file that lacked it and how far the
/// read got.
fn unfinished_json(series: &imu_analysis::ImuSeries) -> Option<serde_json::Value> {
    let u = series.unfinished.as_ref()?;
    let file = series.input.unfinished_file.clone().unwrap_or_default();
    Some(imu_cli::unfinished::json(&file, u))
}
