//! The simulator's ground truth: what the virtual device was really exposed to, sample by sample.
//!
//! `imu-sim` writes one [`TruthSample`] for every data-bearing reply it sends (in the order sent,
//! with the reply's timer ticks), one [`TruthSegment`] whenever the scenario enters a new segment,
//! and metadata holding the scenario text, the seed and the truth error model (a calibration file
//! in the `imu-model` format). A reader matches streamed replies to truth records in order, using
//! the ticks to re-align after a lost frame.
//!
//! Messages are JSON with a JSON Schema, so the file opens as-is in Foxglove, the `mcap` CLI and
//! Python's `mcap` package.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::mcap_read::{self, McapReadError, ReadReport};

/// Topic of [`TruthSample`] messages.
pub const SAMPLE_TOPIC: &str = "/truth/sample";
/// Topic of [`TruthSegment`] messages.
pub const SEGMENT_TOPIC: &str = "/truth/segment";
/// Metadata record holding the run's identity (`scenario-name`, `seed`, `rate-hz`, ...).
pub const RUN_METADATA: &str = "imu-sim.run";
/// Metadata record whose `toml` key holds the scenario file text.
pub const SCENARIO_METADATA: &str = "imu-sim.scenario";
/// Metadata record whose `toml` key holds the truth error model (imu-model calibration format).
pub const TRUTH_MODEL_METADATA: &str = "imu-sim.truth-model";

/// The 3DM-GX1's temperature reply code (`imu_proto::Command::Temperature`): the one truth
/// record that is not a data sample (imu-rec does not depend on the codec; a test in
/// imu-analysis holds the two equal).
pub const TEMPERATURE_COMMAND: u8 = 0x07;

/// True when a truth record with this `command` is a data sample: any GX1 data reply (0x01
/// raw bits, 0x02/0x03 vectors, ...) or a MIP IMU packet (0x80), not a temperature.
pub fn is_data_command(command: u8) -> bool {
    command != TEMPERATURE_COMMAND
}

/// The true state behind one data reply of the virtual device.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthSample {
    /// Index of this data reply since the simulator started (0-based, no gaps).
    pub seq: u64,
    /// Reply header byte (e.g. 0x01 raw sensor bits, 0x07 temperature).
    pub command: u8,
    /// The 16-bit timer ticks carried by the reply.
    pub ticks: u16,
    /// The same ticks unwrapped (+65536 per wrap) since power-on.
    pub ticks_unwrapped: u64,
    /// True time of the sample since the scenario clock started, seconds.
    pub t_s: f64,
    /// True time since the device was powered on (drives warm-up effects), seconds.
    pub time_since_power_on_s: f64,
    /// Index of the scenario segment the sample belongs to.
    pub segment: u32,
    /// True specific force at the sensor, sensor frame, m/s^2.
    pub specific_force_m_s2: [f64; 3],
    /// True angular rate (inertial, so including Earth rate), sensor frame, rad/s.
    pub angular_rate_rad_s: [f64; 3],
    /// True angular acceleration, sensor frame, rad/s^2.
    pub angular_accel_rad_s2: [f64; 3],
    /// True magnetic field, sensor frame, gauss.
    pub mag_field_gauss: [f64; 3],
    /// True sensor temperature, deg C.
    pub temp_c: f64,
    /// Orientation as a unit quaternion `[w, x, y, z]` rotating sensor-frame vectors into the
    /// local East-North-Up frame (`enu_from_sensor`).
    pub enu_from_sensor: [f64; 4],
    /// Angle turned by the table in the current segment group about its axis, rad.
    pub table_angle_rad: f64,
    /// Table rate about its axis, rad/s.
    pub table_rate_rad_s: f64,
    /// What the sensor output before quantization (truth model + noise), m/s^2.
    pub measured_accel_m_s2: [f64; 3],
    /// What the sensor output before quantization (truth model + noise), rad/s.
    pub measured_gyro_rad_s: [f64; 3],
    /// What the sensor output before quantization (truth model + noise), gauss.
    pub measured_mag_gauss: [f64; 3],
    /// True when any channel of the reply hit the 16-bit limits.
    pub saturated: bool,
}

/// One segment of a scenario, as run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthSegment {
    /// Segment index (matches [`TruthSample::segment`]).
    pub index: u32,
    /// What kind of motion: `static`, `move`, `rate`, `impacts`.
    pub kind: String,
    /// Human-readable label, e.g. `index-table position 3 (60 deg about +y)`.
    pub label: String,
    /// Scenario time the segment starts, seconds.
    pub start_s: f64,
    /// Scenario time the segment ends, seconds (`None` for an endless last segment).
    pub end_s: Option<f64>,
    /// Gravity's direction in the sensor frame at the segment start (unit vector pointing down).
    pub gravity_dir_sensor: [f64; 3],
    /// The table axis in the sensor frame (unit vector) for motion segments.
    pub axis_sensor: Option<[f64; 3]>,
    /// The plateau table rate of a `rate` segment, rad/s (relative to the Earth).
    pub table_rate_rad_s: Option<f64>,
}

/// Errors writing a truth file.
#[derive(Debug, thiserror::Error)]
pub enum TruthWriteError {
    /// Creating or writing the file failed.
    #[error("{path}: cannot write truth file")]
    Io {
        /// The truth file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP writer failed.
    #[error("{path}: cannot write truth file")]
    Mcap {
        /// The truth file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: mcap::McapError,
    },
}

/// Writes a truth MCAP file (zstd chunks, summary and index on [`TruthWriter::finish`]).
pub struct TruthWriter<W: Write + Seek = BufWriter<File>> {
    path: PathBuf,
    writer: mcap::Writer<W>,
    sample_channel: u16,
    segment_channel: u16,
    n_samples: u32,
    n_segments: u32,
}

fn json_schema(title: &str) -> String {
    // A permissive schema is enough for Foxglove and the mcap CLI to show the fields; the Rust
    // types above are the authoritative definition.
    format!(r#"{{"title":"{title}","type":"object"}}"#)
}

impl TruthWriter<BufWriter<File>> {
    /// Creates `path` and writes the run's metadata.
    pub fn create(
        path: &Path,
        run: &BTreeMap<String, String>,
        scenario_toml: &str,
        truth_model_toml: &str,
    ) -> Result<Self, TruthWriteError> {
        let file = File::create(path).map_err(|source| TruthWriteError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::new(
            path,
            BufWriter::new(file),
            run,
            scenario_toml,
            truth_model_toml,
        )
    }
}

impl<W: Write + Seek> TruthWriter<W> {
    /// Wraps any seekable sink (`path` is only used in messages).
    pub fn new(
        path: &Path,
        sink: W,
        run: &BTreeMap<String, String>,
        scenario_toml: &str,
        truth_model_toml: &str,
    ) -> Result<Self, TruthWriteError> {
        let mcap_err = |source| TruthWriteError::Mcap {
            path: path.to_path_buf(),
            source,
        };
        let options = mcap::WriteOptions::new()
            .profile("")
            .library(concat!("imu-rec ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(256 * 1024));
        let mut writer = options.create(sink).map_err(mcap_err)?;
        let sample_schema = writer
            .add_schema(
                "imud.TruthSample",
                "jsonschema",
                json_schema("imud.TruthSample").as_bytes(),
            )
            .map_err(mcap_err)?;
        let segment_schema = writer
            .add_schema(
                "imud.TruthSegment",
                "jsonschema",
                json_schema("imud.TruthSegment").as_bytes(),
            )
            .map_err(mcap_err)?;
        let no_meta = BTreeMap::new();
        let sample_channel = writer
            .add_channel(sample_schema, SAMPLE_TOPIC, "json", &no_meta)
            .map_err(mcap_err)?;
        let segment_channel = writer
            .add_channel(segment_schema, SEGMENT_TOPIC, "json", &no_meta)
            .map_err(mcap_err)?;
        let meta = |name: &str, metadata: BTreeMap<String, String>| mcap::records::Metadata {
            name: name.to_string(),
            metadata,
        };
        writer
            .write_metadata(&meta(RUN_METADATA, run.clone()))
            .map_err(mcap_err)?;
        writer
            .write_metadata(&meta(
                SCENARIO_METADATA,
                BTreeMap::from([("toml".to_string(), scenario_toml.to_string())]),
            ))
            .map_err(mcap_err)?;
        writer
            .write_metadata(&meta(
                TRUTH_MODEL_METADATA,
                BTreeMap::from([("toml".to_string(), truth_model_toml.to_string())]),
            ))
            .map_err(mcap_err)?;
        Ok(Self {
            path: path.to_path_buf(),
            writer,
            sample_channel,
            segment_channel,
            n_samples: 0,
            n_segments: 0,
        })
    }

    fn write_json(
        &mut self,
        channel_id: u16,
        sequence: u32,
        t_s: f64,
        data: &[u8],
    ) -> Result<(), TruthWriteError> {
        let time_ns = (t_s.max(0.0) * 1e9).round() as u64;
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time: time_ns,
            publish_time: time_ns,
        };
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|source| TruthWriteError::Mcap {
                path: self.path.clone(),
                source,
            })
    }

    /// Appends one sample (log time = its scenario time).
    pub fn write_sample(&mut self, sample: &TruthSample) -> Result<(), TruthWriteError> {
        let data = serde_json::to_vec(sample).expect("truth samples always serialize");
        self.n_samples = self.n_samples.wrapping_add(1);
        self.write_json(self.sample_channel, self.n_samples, sample.t_s, &data)
    }

    /// Appends one segment record (log time = its start).
    pub fn write_segment(&mut self, segment: &TruthSegment) -> Result<(), TruthWriteError> {
        let data = serde_json::to_vec(segment).expect("truth segments always serialize");
        self.n_segments = self.n_segments.wrapping_add(1);
        self.write_json(
            self.segment_channel,
            self.n_segments,
            segment.start_s,
            &data,
        )
    }

    /// Ends the current chunk and flushes it to the sink, so that a reader sees everything
    /// written so far even if this process dies.
    pub fn flush(&mut self) -> Result<(), TruthWriteError> {
        self.writer.flush().map_err(|source| TruthWriteError::Mcap {
            path: self.path.clone(),
            source,
        })
    }

    /// Writes the summary and index and closes the file.
    pub fn finish(mut self) -> Result<(), TruthWriteError> {
        self.writer
            .finish()
            .map_err(|source| TruthWriteError::Mcap {
                path: self.path.clone(),
                source,
            })?;
        Ok(())
    }
}

/// A whole truth file in memory (fine for test-sized runs; see [`read_truth_streaming`] for long
/// ones).
#[derive(Debug, Clone, Default)]
pub struct Truth {
    /// Every sample, in the order the device sent them.
    pub samples: Vec<TruthSample>,
    /// Every segment, in order.
    pub segments: Vec<TruthSegment>,
    /// Run identity (`seed`, `scenario-name`, `rate-hz`, `tick-period-s`, ...).
    pub run: BTreeMap<String, String>,
    /// The scenario file text.
    pub scenario_toml: String,
    /// The truth error model text (imu-model calibration format).
    pub truth_model_toml: String,
    /// What the reader saw (truncation, channels).
    pub report: ReadReport,
}

/// Reads a truth file, calling `on_sample` and `on_segment` as records stream by; returns the
/// report with the run metadata.
pub fn read_truth_streaming(
    path: &Path,
    mut on_sample: impl FnMut(TruthSample),
    mut on_segment: impl FnMut(TruthSegment),
) -> Result<ReadReport, McapReadError> {
    mcap_read::for_each_message(path, |channel, _header, data| {
        match channel.topic.as_str() {
            SAMPLE_TOPIC => on_sample(serde_json::from_slice(data).map_err(|e| e.to_string())?),
            SEGMENT_TOPIC => on_segment(serde_json::from_slice(data).map_err(|e| e.to_string())?),
            _ => {}
        }
        Ok(())
    })
}

/// Reads a whole truth file into memory.
pub fn read_truth(path: &Path) -> Result<Truth, McapReadError> {
    let mut samples = Vec::new();
    let mut segments = Vec::new();
    let report = read_truth_streaming(path, |s| samples.push(s), |s| segments.push(s))?;
    let text = |name: &str| {
        report
            .metadata
            .get(name)
            .and_then(|m| m.get("toml"))
            .cloned()
            .unwrap_or_default()
    };
    Ok(Truth {
        samples,
        segments,
        run: report
            .metadata
            .get(RUN_METADATA)
            .cloned()
            .unwrap_or_default(),
        scenario_toml: text(SCENARIO_METADATA),
        truth_model_toml: text(TRUTH_MODEL_METADATA),
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(seq: u64) -> TruthSample {
        TruthSample {
            seq,
            command: 0x01,
            ticks: (seq * 2 % 65536) as u16,
            ticks_unwrapped: seq * 2,
            t_s: seq as f64 * 0.01,
            time_since_power_on_s: seq as f64 * 0.01 + 1.0,
            segment: (seq / 100) as u32,
            specific_force_m_s2: [0.0, 0.0, 9.80665],
            angular_rate_rad_s: [1e-5, 5e-5, 4e-5],
            angular_accel_rad_s2: [0.0; 3],
            mag_field_gauss: [0.0, 0.22, -0.42],
            temp_c: 25.0 + seq as f64 * 1e-3,
            enu_from_sensor: [1.0, 0.0, 0.0, 0.0],
            table_angle_rad: 0.0,
            table_rate_rad_s: 0.0,
            measured_accel_m_s2: [0.01, -0.02, 9.81],
            measured_gyro_rad_s: [0.001; 3],
            measured_mag_gauss: [0.0, 0.22, -0.42],
            saturated: false,
        }
    }

    fn segment(index: u32) -> TruthSegment {
        TruthSegment {
            index,
            kind: "static".into(),
            label: format!("segment {index}"),
            start_s: index as f64,
            end_s: Some(index as f64 + 1.0),
            gravity_dir_sensor: [0.0, 0.0, -1.0],
            axis_sensor: None,
            table_rate_rad_s: None,
        }
    }

    fn write_file(path: &Path, n: u64, finish: bool) {
        let run = BTreeMap::from([("seed".to_string(), "7".to_string())]);
        let mut w = TruthWriter::create(path, &run, "name = \"x\"", "format = \"y\"").unwrap();
        for i in 0..n {
            if i % 100 == 0 {
                w.write_segment(&segment((i / 100) as u32)).unwrap();
            }
            w.write_sample(&sample(i)).unwrap();
            if i % 1000 == 999 {
                w.flush().unwrap();
            }
        }
        if finish {
            w.finish().unwrap();
        } else {
            w.flush().unwrap();
            // Never finished (the writer's Drop would write the summary): what a killed process
            // leaves behind.
            std::mem::forget(w);
        }
    }

    #[test]
    fn round_trip_keeps_every_record_and_the_metadata() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("truth.mcap");
        write_file(&path, 2500, true);
        let truth = read_truth(&path).unwrap();
        assert_eq!(truth.samples.len(), 2500);
        assert_eq!(truth.segments.len(), 25);
        assert_eq!(truth.samples[1234], sample(1234));
        assert_eq!(truth.segments[7], segment(7));
        assert_eq!(truth.run.get("seed").map(String::as_str), Some("7"));
        assert_eq!(truth.scenario_toml, "name = \"x\"");
        assert_eq!(truth.truth_model_toml, "format = \"y\"");
        assert!(truth.report.stopped_early.is_none());
    }

    #[test]
    fn truncated_file_reads_up_to_the_last_good_record() {
        let dir = tempfile::tempdir().unwrap();
        let full = dir.path().join("full.mcap");
        write_file(&full, 5000, false);
        let bytes = std::fs::read(&full).unwrap();
        // Cut inside the data section: the reader must deliver a gap-free prefix and say it stopped.
        let cut = dir.path().join("cut.mcap");
        std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
        let truth = read_truth(&cut).unwrap();
        assert!(truth.report.stopped_early.is_some());
        assert!(!truth.samples.is_empty());
        assert!(truth.samples.len() < 5000);
        for (i, s) in truth.samples.iter().enumerate() {
            assert_eq!(s.seq, i as u64, "prefix must be gap-free");
        }
        // The unfinished (never summarised) file still yields everything flushed.
        let unfinished = read_truth(&full).unwrap();
        assert_eq!(unfinished.samples.len(), 5000);
        assert!(unfinished.report.stopped_early.is_some());
    }

    #[test]
    fn not_an_mcap_file_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("junk.mcap");
        std::fs::write(&path, b"definitely not mcap").unwrap();
        let err = read_truth(&path).unwrap_err().to_string();
        assert!(
            err.contains("junk.mcap") && err.contains("not an MCAP"),
            "{err}"
        );
    }
}
