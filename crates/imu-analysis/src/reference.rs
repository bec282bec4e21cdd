//! References: where the TRUE input of each detected segment comes from. A calibration fit
//! compares each segment's measured mean with the input the sensor really had; that input is
//! known from a reference: the simulator's truth recording (sample-aligned with an offline
//! recording; in memory or streamed from its file), a test plan stating the procedure's nominal inputs ([`crate::plan`]), or a
//! time-stamped reference log such as a rate table's ([`crate::reference_log`]).

use std::path::PathBuf;

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
    /// The simulator's truth, read from its file as it streams by: only the segment means are kept, so a
    /// 6-hour truth file (2 million samples, 0.5 GB in memory) costs no memory.
    TruthFile(PathBuf),
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
            // Streamed into segment means when used: hours of truth cost no memory.
            return Ok(Some(Reference::TruthFile(path.to_path_buf())));
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
    /// quadrature to the gyro bias standard errors ([`crate::fit::FitOptions::bias_input_uncertainty`]).
    pub gyro_bias_std_rad_s: Option<[f64; 3]>,
    /// Remarks (gravity used, time offset found, assumptions).
    pub notes: Vec<String>,
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
            Reference::Truth(_) | Reference::TruthFile(_) | Reference::Log(_) => {
                Ok(crate::segment::detect(series, opts)?)
            }
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
        }
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        match self {
            Reference::Truth(t) => format!("simulator truth ({} samples)", t.samples.len()),
            Reference::Plan(p) => p.describe(),
            Reference::Log(l) => l.describe(),
            Reference::TruthFile(p) => format!("simulator truth {}", p.display()),
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
/// temperature readings (else `fallback_temp_c`, else [`imu_model::units::REFERENCE_TEMP_C`]) and its
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
        fallback_temp_c.unwrap_or(imu_model::units::REFERENCE_TEMP_C)
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
    /// The truth file could not be read.
    #[error(transparent)]
    Read(#[from] imu_bus::McapReadError),
    /// A truth sample could not be decoded.
    #[error("{path}: truth sample: {message}")]
    Parse {
        /// The truth file.
        path: PathBuf,
        /// What the JSON decoder said.
        message: String,
    },
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

/// The fields of a truth sample a segment mean needs (the rest of the JSON is skipped unparsed).
#[derive(serde::Deserialize)]
struct TruthInput {
    command: u8,
    specific_force_m_s2: [f64; 3],
    angular_rate_rad_s: [f64; 3],
    temp_c: f64,
    time_since_power_on_s: f64,
}

/// Sums truth samples into their segments' means, one data sample after the other.
struct SegmentAccumulator<'a> {
    segments: &'a [Segment],
    /// Segment indices in sample order, so one forward pass finds each sample's segment.
    order: Vec<usize>,
    next: usize,
    /// Data samples seen.
    k: usize,
    out: Vec<SegmentTruth>,
}

impl<'a> SegmentAccumulator<'a> {
    fn new(segments: &'a [Segment]) -> Self {
        let mut order: Vec<usize> = (0..segments.len()).collect();
        order.sort_by_key(|&i| segments[i].first_sample);
        let zero = SegmentTruth {
            specific_force_m_s2: [0.0; 3],
            angular_rate_rad_s: [0.0; 3],
            temp_c: 0.0,
            time_since_power_on_s: 0.0,
        };
        SegmentAccumulator {
            segments,
            order,
            next: 0,
            k: 0,
            out: vec![zero; segments.len()],
        }
    }

    /// One truth message (JSON); data samples (command 0x01) count, others are skipped.
    fn add(&mut self, json: &[u8]) -> Result<(), String> {
        let s: TruthInput = serde_json::from_slice(json).map_err(|e| e.to_string())?;
        if s.command != 0x01 {
            return Ok(());
        }
        let k = self.k;
        self.k += 1;
        while self.next < self.order.len() && self.segments[self.order[self.next]].range().end <= k
        {
            self.next += 1;
        }
        if let Some(&i) = self.order.get(self.next)
            && self.segments[i].range().contains(&k)
        {
            let (n, acc) = (self.segments[i].n as f64, &mut self.out[i]);
            for a in 0..3 {
                acc.specific_force_m_s2[a] += s.specific_force_m_s2[a] / n;
                acc.angular_rate_rad_s[a] += s.angular_rate_rad_s[a] / n;
            }
            acc.temp_c += s.temp_c / n;
            acc.time_since_power_on_s += s.time_since_power_on_s / n;
        }
        Ok(())
    }
}

/// Truth messages handed from the reading thread to the parsing thread at a time.
const BATCH_MESSAGES: usize = 4096;

/// [`truth_for_segments`] streaming the truth file: the k-th data sample (command 0x01) is added
/// to the segment holding sample k. Decompression (this thread) and JSON parsing (a second
/// thread, fed in order through a short queue) overlap; memory stays a few batches.
pub fn truth_file_for_segments(
    series: &ImuSeries,
    segments: &[Segment],
    path: &std::path::Path,
) -> Result<Vec<SegmentTruth>, ReferenceError> {
    let (read, parsed) = std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<Vec<u8>>>(4);
        let parser = scope.spawn(move || {
            let mut acc = SegmentAccumulator::new(segments);
            for batch in rx {
                for json in &batch {
                    acc.add(json)?;
                }
            }
            Ok::<_, String>((acc.k, acc.out))
        });
        let mut batch = Vec::with_capacity(BATCH_MESSAGES);
        let read = imu_bus::mcap_read::for_each_message(path, |channel, _header, data| {
            if channel.topic == imu_bus::truth::SAMPLE_TOPIC {
                batch.push(data.to_vec());
                if batch.len() == BATCH_MESSAGES {
                    let full = std::mem::replace(&mut batch, Vec::with_capacity(BATCH_MESSAGES));
                    // A closed queue means the parser failed; its error is reported below.
                    let _ = tx.send(full);
                }
            }
            Ok(())
        });
        let _ = tx.send(batch);
        drop(tx);
        (read, parser.join().expect("truth parser thread"))
    });
    read?;
    let (k, out) = parsed.map_err(|message| ReferenceError::Parse {
        path: path.to_path_buf(),
        message,
    })?;
    if k < series.len() {
        return Err(ReferenceError::TooShort {
            truth_samples: k,
            series_samples: series.len(),
        });
    }
    Ok(out)
}
