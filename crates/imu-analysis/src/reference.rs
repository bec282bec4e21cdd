//! References: where the TRUE input of each detected segment comes from. A calibration fit
//! compares each segment's measured mean with the input the sensor really had; that input is
//! known from a reference. Today: the simulator's truth recording (sample-aligned with an
//! offline recording).

use crate::ImuSeries;
use crate::segment::Segment;

/// A source of the true input over segments.
#[derive(Clone, Debug)]
pub enum Reference {
    /// The simulator's truth MCAP of this very recording (one truth sample per data sample).
    Truth(imu_bus::truth::Truth),
}

impl Reference {
    /// The mean true input over each of `segments` of `series`.
    pub fn segment_truth(
        &self,
        series: &ImuSeries,
        segments: &[Segment],
    ) -> Result<Vec<SegmentTruth>, ReferenceError> {
        match self {
            Reference::Truth(t) => truth_for_segments(series, segments, t),
        }
    }

    /// One-line description for reports and provenance.
    pub fn describe(&self) -> String {
        match self {
            Reference::Truth(t) => format!("simulator truth ({} samples)", t.samples.len()),
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
