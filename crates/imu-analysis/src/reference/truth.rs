//! The simulator's truth as a reference: sample-aligned with an offline recording, in memory or
//! streamed from its file into segment means for hours-long runs.

use super::*;

/// Mean truth over each segment's samples. In an offline recording the k-th data sample is the
/// k-th truth data record (`imu_rec::truth::is_data_command`: any protocol's data, not a
/// temperature; same order, no gaps), so the truth is averaged over exactly the samples of the
/// segment.
pub fn truth_for_segments(
    series: &ImuSeries,
    segments: &[Segment],
    truth: &imu_rec::truth::Truth,
) -> Result<Vec<SegmentTruth>, ReferenceError> {
    let data: Vec<&imu_rec::truth::TruthSample> = truth
        .samples
        .iter()
        .filter(|s| imu_rec::truth::is_data_command(s.command))
        .collect();
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
pub(super) struct TruthInput {
    command: u8,
    specific_force_m_s2: [f64; 3],
    angular_rate_rad_s: [f64; 3],
    temp_c: f64,
    time_since_power_on_s: f64,
}

/// Sums truth samples into their segments' means, one data sample after the other.
pub(super) struct SegmentAccumulator<'a> {
    segments: &'a [Segment],
    /// Segment indices in sample order, so one forward pass finds each sample's segment.
    order: Vec<usize>,
    next: usize,
    /// Data samples seen.
    k: usize,
    out: Vec<SegmentTruth>,
}

impl<'a> SegmentAccumulator<'a> {
    pub(super) fn new(segments: &'a [Segment]) -> Self {
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

    /// One truth message (JSON); data samples count, temperatures are skipped.
    pub(super) fn add(&mut self, json: &[u8]) -> Result<(), String> {
        let s: TruthInput = serde_json::from_slice(json).map_err(|e| e.to_string())?;
        if !imu_rec::truth::is_data_command(s.command) {
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
pub(super) const BATCH_MESSAGES: usize = 4096;

/// [`truth_for_segments`] streaming the truth file: the k-th data sample is added
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
        let read = imu_rec::mcap_read::for_each_message(path, |channel, _header, data| {
            if channel.topic == imu_rec::truth::SAMPLE_TOPIC {
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

#[cfg(test)]
mod tests {
    #[test]
    fn the_truth_files_temperature_code_is_the_codecs() {
        assert_eq!(
            imu_rec::truth::TEMPERATURE_COMMAND,
            imu_proto::Command::Temperature.code()
        );
        assert!(imu_rec::truth::is_data_command(0x80));
        assert!(imu_rec::truth::is_data_command(0x01));
    }
}
