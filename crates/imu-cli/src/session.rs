//! What every offline client says about the recording it read (feature `analysis`): a file read
//! without its footer (the one-line warning of `unfinished`), each time gap between the
//! files of a session, and samples skipped for a NaN or infinite value, on stderr; the same facts for `--json` are the series' `input` (files,
//! topic, gaps) and the unfinished note this returns.

use imu_analysis::ImuSeries;

/// Warns on stderr as `tool: warning: ...` about an unfinished file, every gap between
/// files and skipped non-finite samples; returns the unfinished file's JSON note (`None` for a complete input).
pub fn warn(tool: &str, series: &ImuSeries) -> Option<serde_json::Value> {
    for line in gap_warnings(series) {
        eprintln!("{tool}: warning: {line}");
    }
    if let Some(line) = non_finite_warning(series) {
        eprintln!("{tool}: warning: {line}");
    }
    let path = series
        .input
        .unfinished_file
        .clone()
        .or_else(|| series.input.files.first().cloned())
        .unwrap_or_default();
    crate::unfinished::warn(tool, &path, series.unfinished.as_ref())
}

/// One line per gap between consecutive files.
pub fn gap_warnings(series: &ImuSeries) -> Vec<String> {
    series
        .input
        .gaps
        .iter()
        .map(|g| {
            format!(
                "{:.3} s gap ({} samples missing) at {:.3} s between {} and {}: the files are \
                 read as one recording; analyses spanning the gap see a jump in time",
                g.gap_s,
                g.missing_samples,
                g.at_s,
                g.after.display(),
                g.before.display()
            )
        })
        .collect()
}

/// The samples skipped for a NaN or infinite value, if any.
pub fn non_finite_warning(series: &ImuSeries) -> Option<String> {
    let n = series.input.non_finite_samples;
    (n > 0).then(|| {
        format!(
            "{n} samples skipped: a value was NaN or infinite (the unit or the writer had no \
             reading); they count among the samples missing"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use imu_analysis::input::{InputInfo, SessionGap};

    #[test]
    fn a_gap_is_said_with_its_files_and_size() {
        let s = ImuSeries {
            input: InputInfo {
                files: vec!["a.mcap".into(), "b.mcap".into()],
                gaps: vec![SessionGap {
                    after: "a.mcap".into(),
                    before: "b.mcap".into(),
                    at_s: 3600.0,
                    gap_s: 2.5,
                    missing_samples: 249,
                }],
                ..InputInfo::default()
            },
            ..ImuSeries::default()
        };
        let w = gap_warnings(&s);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with(
                "2.500 s gap (249 samples missing) at 3600.000 s between a.mcap and b.mcap"
            ),
            "{}",
            w[0]
        );
        assert_eq!(warn("t", &s), None);
        assert_eq!(non_finite_warning(&s), None);
        let skipped = ImuSeries {
            input: InputInfo {
                non_finite_samples: 3,
                ..InputInfo::default()
            },
            ..ImuSeries::default()
        };
        assert!(
            non_finite_warning(&skipped)
                .is_some_and(|w| w.starts_with("3 samples skipped: a value was NaN or infinite")),
        );
    }
}
