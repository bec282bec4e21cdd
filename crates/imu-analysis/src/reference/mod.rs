//! References: where the TRUE input of each detected segment comes from. A calibration fit
//! compares each segment's measured mean with the input the sensor really had; that input is
//! known from a reference: the simulator's truth recording (sample-aligned with an offline
//! recording; in memory or streamed from its file), a test plan stating the procedure's nominal inputs ([`plan`]), or a
//! time-stamped reference log such as a rate table's ([`log`]).

use std::path::PathBuf;

use crate::ImuSeries;
pub mod direction;
pub mod ferraris;
pub mod log;
pub mod plan;

use crate::segment::{Segment, SegmentError, SegmentOptions, Segmentation};
use log::{AlignedLog, ReferenceLogError};
use plan::{Plan, PlanMismatch, PlanSegmentationError};

pub mod segment_truth;
pub mod truth;

pub use segment_truth::*;
pub use truth::*;

/// A source of the true input over segments.
#[derive(Clone, Debug)]
pub enum Reference {
    /// The simulator's truth MCAP of this very recording (one truth sample per data sample).
    Truth(imu_rec::truth::Truth),
    /// A test plan: the procedure's nominal inputs, matched in order to the segments.
    Plan(Plan),
    /// A time-stamped reference log (CSV), aligned in time with the recording.
    Log(AlignedLog),
    /// The simulator's truth, read from its file as it streams by: only the segment means are kept, so a
    /// 6-hour truth file (2 million samples, 0.5 GB in memory) costs no memory.
    TruthFile(PathBuf),
    /// The Ferraris procedure (a plan file with `procedure = "ferraris"`): six still faces in
    /// any order and a full turn about each axis, recognised from the data.
    Ferraris(ferraris::Ferraris),
}

/// Failures of [`Reference::open`].
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The test plan file is invalid (its message names file and line).
    #[error(transparent)]
    Plan(#[from] plan::PlanError),
    /// A Ferraris plan file has an invalid key or value.
    #[error("{0}")]
    Ferraris(String),
    /// The reference file could not be read.
    #[error("reading reference {path}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
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

/// True if the file starts with the MCAP magic bytes (the one check, in imu-bus).
fn is_mcap(path: &std::path::Path) -> std::io::Result<bool> {
    imu_rec::mcap_read::has_mcap_magic(path)
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
            // A Ferraris plan names its procedure; any other file (or unreadable text) is a
            // step plan, whose reader reports what is wrong with it.
            let text = std::fs::read_to_string(path).unwrap_or_default();
            if let Some(f) = ferraris::Ferraris::from_toml_str(&text, &path.display().to_string()) {
                return Ok(Some(Reference::Ferraris(f.map_err(OpenError::Ferraris)?)));
            }
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
            // Streamed into segment means when used: hours of truth cost no memory.
            return Ok(Some(Reference::TruthFile(path.to_path_buf())));
        }
        let log = log::ReferenceLog::load(path)?;
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
    /// quadrature to the gyro bias standard errors ([`crate::calibrate::FitOptions::bias_input_uncertainty`]).
    pub gyro_bias_std_rad_s: Option<[f64; 3]>,
    /// Remarks (gravity used, time offset found, assumptions).
    pub notes: Vec<crate::note::Note>,
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
            Reference::Plan(p) => Ok(p.segmentation(series, opts)?),
            Reference::Truth(_) | Reference::TruthFile(_) | Reference::Log(_) => {
                Ok(crate::segment::detect(series, opts)?)
            }
            Reference::Ferraris(f) => Ok(f.segmentation(series, opts)?),
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
            Reference::TruthFile(path) => truth_file_for_segments(series, segments, path),
            Reference::Plan(p) => Ok(p.segment_truth(series, segments)?),
            Reference::Log(l) => Ok(l.segment_truth(series, segments)?),
            Reference::Ferraris(f) => Ok(f.segment_truth(series, segments)?),
        }
    }

    /// What the reference leaves unknown about the true input of `segments`, and notes.
    pub fn caveats(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<ReferenceCaveats, ReferenceError> {
        match self {
            Reference::Truth(_) | Reference::TruthFile(_) => Ok(ReferenceCaveats::default()),
            Reference::Plan(p) => {
                let c = p.caveats(series, segments)?;
                Ok(ReferenceCaveats {
                    gyro_bias_std_rad_s: c.gyro_bias_std_rad_s,
                    notes: c.notes,
                })
            }
            Reference::Log(l) => Ok(ReferenceCaveats {
                gyro_bias_std_rad_s: l.gyro_bias_std_rad_s(segments),
                notes: l.notes(series),
            }),
            Reference::Ferraris(f) => Ok(f.caveats(segments)),
        }
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        match self {
            Reference::Truth(t) => format!("simulator truth ({} samples)", t.samples.len()),
            Reference::Plan(p) => p.describe(),
            Reference::Log(l) => l.describe(),
            Reference::TruthFile(p) => format!("simulator truth {}", p.display()),
            Reference::Ferraris(f) => f.describe(),
        }
    }
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
    /// The recording does not follow the Ferraris procedure.
    #[error(transparent)]
    Ferraris(#[from] ferraris::FerrarisError),
    /// The recording does not follow the test plan.
    #[error(transparent)]
    Plan(#[from] PlanMismatch),
    /// The reference log does not cover or fit the recording.
    #[error(transparent)]
    Log(#[from] ReferenceLogError),
    /// The truth file could not be read.
    #[error(transparent)]
    Read(#[from] imu_rec::McapReadError),
    /// A truth sample could not be decoded.
    #[error("{path}: truth sample: {message}")]
    Parse {
        /// The truth file.
        path: PathBuf,
        /// What the JSON decoder said.
        message: String,
    },
}

impl From<PlanSegmentationError> for ReferenceError {
    fn from(e: PlanSegmentationError) -> Self {
        match e {
            PlanSegmentationError::Segment(e) => ReferenceError::Segment(e),
            PlanSegmentationError::Mismatch(m) => ReferenceError::Plan(m),
        }
    }
}
