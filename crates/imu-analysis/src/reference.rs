//! References: where the TRUE input of each detected segment comes from. A calibration fit
//! compares each segment's measured mean with the input the sensor really had; that input is
//! known from a reference: the simulator's truth recording (sample-aligned with an offline
//! recording), a test plan stating the procedure's nominal inputs ([`crate::plan`]), or a
//! time-stamped reference log such as a rate table's ([`crate::reference_log`]).

use crate::ImuSeries;
use crate::plan::{Plan, PlanMismatch};
use crate::reference_log::{AlignedLog, ReferenceLogError};
use crate::segment::{Segment, SegmentError, SegmentOptions, Segmentation};

/// A source of the true input over segments.
#[derive(Clone, Debug)]
pub enum Reference {
    /// The simulator's truth MCAP of this very recording (one truth sample per data sample).
    Truth(imu_bus::truth::Truth),
    /// A test plan: the procedure's nominal inputs, matched in order to the segments.
    Plan(Plan),
    /// A time-stamped reference log (CSV), aligned in time with the recording.
    Log(AlignedLog),
}

/// Failures of [`Reference::open`].
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The test plan file is invalid (its message names file and line).
    #[error(transparent)]
    Plan(#[from] crate::plan::PlanError),
    /// The reference file could not be read.
    #[error("reading reference {path}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The truth MCAP could not be read.
    #[error("reading reference {path}")]
    Truth {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: imu_bus::mcap_read::McapReadError,
    },
    /// The reference log is invalid or cannot be aligned.
    #[error(transparent)]
    Log(#[from] ReferenceLogError),
    /// A clock offset was given for a truth MCAP.
    #[error("{path}: a clock offset applies to a reference log (CSV), not to a truth MCAP")]
    OffsetOnTruth {
        /// The file.
        path: std::path::PathBuf,
    },
}

/// True if the file starts with the MCAP magic bytes.
fn is_mcap(path: &std::path::Path) -> std::io::Result<bool> {
    use std::io::Read;
    let mut magic = [0u8; 8];
    let n = std::fs::File::open(path)?.read(&mut magic)?;
    Ok(n == 8 && magic == *b"\x89MCAP0\r\n")
}

impl Reference {
    /// The reference the command-line tools were given: a test plan, or a reference file
    /// that is either the simulator's truth MCAP or a reference log (CSV, told apart by the
    /// MCAP magic bytes), aligned with `series` by cross-correlation unless `offset_s` (log
    /// clock minus recording clock) is given. None when neither is given.
    pub fn open(
        plan: Option<&std::path::Path>,
        reference: Option<&std::path::Path>,
        offset_s: Option<f64>,
        series: &ImuSeries,
    ) -> Result<Option<Reference>, OpenError> {
        if let Some(path) = plan {
            return Ok(Some(Reference::Plan(Plan::load(path)?)));
        }
        let Some(path) = reference else {
            return Ok(None);
        };
        let io = |source| OpenError::Io {
            path: path.to_path_buf(),
            source,
        };
        if is_mcap(path).map_err(io)? {
            if offset_s.is_some() {
                return Err(OpenError::OffsetOnTruth {
                    path: path.to_path_buf(),
                });
            }
            let truth = imu_bus::truth::read_truth(path).map_err(|source| OpenError::Truth {
                path: path.to_path_buf(),
                source,
            })?;
            return Ok(Some(Reference::Truth(truth)));
        }
        let log = crate::reference_log::ReferenceLog::load(path)?;
        Ok(Some(Reference::Log(match offset_s {
            Some(o) => log.with_offset(o),
            None => log.align(series)?,
        })))
    }
}

/// What a reference cannot tell about the true input, and remarks for the report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReferenceCaveats {
    /// Systematic uncertainty of the gyro's true input common to the segments, per axis,
    /// rad/s (e.g. Earth's rate where a plan does not fix north); the fit adds it in
    /// quadrature to the gyro bias standard errors, like a bias drift.
    pub gyro_bias_std_rad_s: Option<[f64; 3]>,
    /// Remarks (gravity used, time offset found, assumptions).
    pub notes: Vec<String>,
}

impl ReferenceCaveats {
    /// `drift` widened by the reference's own systematic uncertainty (in quadrature).
    pub fn widen_gyro_bias_drift(&self, drift: Option<[f64; 3]>) -> Option<[f64; 3]> {
        match (drift, self.gyro_bias_std_rad_s) {
            (d, None) => d,
            (None, r) => r,
            (Some(d), Some(r)) => Some(std::array::from_fn(|a| d[a].hypot(r[a]))),
        }
    }
}

impl Reference {
    /// The segments of `series` to fit: detected with `opts`, unless the reference gives them
    /// (a plan with time ranges set by hand).
    pub fn segmentation(
        &self,
        series: &ImuSeries,
        opts: &SegmentOptions,
    ) -> Result<Segmentation, ReferenceError> {
        match self {
            Reference::Plan(p) => p.segmentation(series, opts),
            Reference::Truth(_) | Reference::Log(_) => Ok(crate::segment::detect(series, opts)?),
        }
    }

    /// The mean true input over each of `segments` of `series`.
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, ReferenceError> {
        match self {
            Reference::Truth(t) => truth_for_segments(series, segments, t),
            Reference::Plan(p) => Ok(p.segment_truth(series, segments)?),
            Reference::Log(l) => Ok(l.segment_truth(series, segments)?),
        }
    }

    /// What the reference leaves unknown about the true input of `segments`, and notes.
    pub fn caveats(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<ReferenceCaveats, ReferenceError> {
        match self {
            Reference::Truth(_) => Ok(ReferenceCaveats::default()),
            Reference::Plan(p) => {
                let c = p.caveats(series, segments)?;
                Ok(ReferenceCaveats {
                    gyro_bias_std_rad_s: c.gyro_bias_std_rad_s,
                    notes: c.notes,
                })
            }
            Reference::Log(l) => Ok(ReferenceCaveats {
                gyro_bias_std_rad_s: None,
                notes: l.notes(series),
            }),
        }
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        match self {
            Reference::Truth(t) => format!("simulator truth ({} samples)", t.samples.len()),
            Reference::Plan(p) => p.describe(),
            Reference::Log(l) => l.describe(),
        }
    }
}

/// The true input over one segment, from a reference (sensor frame).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SegmentTruth {
    /// Mean true specific force, m/s^2.
    pub specific_force_m_s2: [f64; 3],
    /// Mean true angular rate (including Earth rate), rad/s.
    pub angular_rate_rad_s: [f64; 3],
    /// Mean true temperature, deg C.
    pub temp_c: f64,
    /// Mean time since power-on, s.
    pub time_since_power_on_s: f64,
}

/// Mean temperature and time since power-on over segment `s`, from the recording itself: its
/// temperature readings (else `fallback_temp_c`, else [`crate::plan::FALLBACK_TEMP_C`]) and its
/// time since the first sample plus `powered_on_before_s`.
pub(crate) fn recording_conditions(
    series: &ImuSeries,
    s: &Segment,
    fallback_temp_c: Option<f64>,
    powered_on_before_s: f64,
) -> (f64, f64) {
    let times = &series.t_s[s.range()];
    let n = times.len().max(1) as f64;
    let temp_c = if series.temp.is_empty() {
        fallback_temp_c.unwrap_or(crate::plan::FALLBACK_TEMP_C)
    } else {
        times.iter().map(|&t| series.temp_at(t)).sum::<f64>() / n
    };
    (temp_c, powered_on_before_s + times.iter().sum::<f64>() / n)
}

/// Failures of the reference alignment.
#[derive(Debug, thiserror::Error)]
pub enum ReferenceError {
    /// The truth file holds fewer data samples than the recording.
    #[error(
        "the reference has {truth_samples} data samples (command 0x01) but the recording \
         {series_samples}: it is not the truth of this recording (or was cut short)"
    )]
    TooShort {
        /// Data samples in the truth.
        truth_samples: usize,
        /// Samples in the series.
        series_samples: usize,
    },
    /// Segmentation failed.
    #[error(transparent)]
    Segment(#[from] SegmentError),
    /// The recording does not follow the test plan.
    #[error(transparent)]
    Plan(#[from] PlanMismatch),
    /// The reference log does not cover or fit the recording.
    #[error(transparent)]
    Log(#[from] ReferenceLogError),
}

/// Mean truth over each segment's samples. In an offline recording the k-th data sample is the
/// k-th truth sample with command 0x01 (same order, no gaps), so the truth is averaged over
/// exactly the samples of the segment.
pub fn truth_for_segments(
    series: &ImuSeries,
    segments: &[Segment],
    truth: &imu_bus::truth::Truth,
) -> Result<Vec<SegmentTruth>, ReferenceError> {
    let data: Vec<&imu_bus::truth::TruthSample> =
        truth.samples.iter().filter(|s| s.command == 0x01).collect();
    if data.len() < series.len() {
        return Err(ReferenceError::TooShort {
            truth_samples: data.len(),
            series_samples: series.len(),
        });
    }
    Ok(segments
        .iter()
        .map(|seg| {
            let n = seg.n as f64;
            let mut out = SegmentTruth {
                specific_force_m_s2: [0.0; 3],
                angular_rate_rad_s: [0.0; 3],
                temp_c: 0.0,
                time_since_power_on_s: 0.0,
            };
            for s in &data[seg.range()] {
                for a in 0..3 {
                    out.specific_force_m_s2[a] += s.specific_force_m_s2[a] / n;
                    out.angular_rate_rad_s[a] += s.angular_rate_rad_s[a] / n;
                }
                out.temp_c += s.temp_c / n;
                out.time_since_power_on_s += s.time_since_power_on_s / n;
            }
            out
        })
        .collect())
}
