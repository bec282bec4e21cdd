//! Text export: a scenario run at CPU speed, without a pty or a host, written as another
//! tool would export a recording: two whitespace-separated text files, `acc.txt` and
//! `gyro.txt`, one `t x y z` line per sample and no header (`imu-sim --export-text DIR`).
//!
//! Each sample is the device's own reply to the raw-sensor-bits poll (0x01) at `k / rate-hz`:
//! the same physics, truth model, noise and quantisation as any data reply, and with
//! `--truth-out` the same truth records. [`ExportUnits::RawCounts`] writes those 16-bit
//! counts as the device gives them (unsigned, zero at mid-scale 32768, one count
//! `GainScale / 32 768 000` g or rad/s); [`ExportUnits::Si`] writes them converted to m/s^2
//! and rad/s with the device's GainScales.
//!
//! [`export_parts`] (`imu-sim --export-parts FILE.csv`) writes a labelled session as labs
//! export one for the Python package imucal: the scenario's parts only (segments with a `part`,
//! each run of one part's segments as one part, the moves between them cut out, so the parts
//! follow each other with no motion between them), one CSV with a header `part, samples, acc_x,
//! acc_y, acc_z, gyr_x, gyr_y, gyr_z`, `samples` the index within the part (restarting at 0),
//! no time column, the counts signed about mid-scale, and the gyro's optionally negated (a unit
//! whose gyro reports rotation the other way).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use imu_proto::{Command, Reply, scale};

use crate::{DeviceCore, SimError, SimOptions, open_truth};

/// What the exported numbers are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExportUnits {
    /// The device's raw 16-bit counts, unsigned around 32768 (`raw-counts`).
    #[default]
    RawCounts,
    /// m/s^2 and rad/s through the device's GainScales (`si`).
    Si,
}

impl std::str::FromStr for ExportUnits {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "raw-counts" => Ok(Self::RawCounts),
            "si" => Ok(Self::Si),
            _ => Err(format!("`{s}` is not an export unit: raw-counts or si")),
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct TextExport {
    /// The accelerometer file.
    pub accel: PathBuf,
    /// The gyro file.
    pub gyro: PathBuf,
    /// Samples in each.
    pub samples: u64,
    /// One accelerometer count, m/s^2 (the `SCALE` of a reader's `counts:SCALE@32768`).
    pub accel_count_m_s2: f64,
    /// One gyro count, rad/s.
    pub gyro_count_rad_s: f64,
}

/// Runs `opts`'s scenario (which must end) and writes `dir/acc.txt` and `dir/gyro.txt`, and
/// the truth file when `opts.truth_out` asks for one.
pub fn export_text(
    opts: &SimOptions,
    dir: &Path,
    units: ExportUnits,
) -> Result<TextExport, SimError> {
    let mut core = DeviceCore::new(opts.scenario.clone(), opts.truth.clone(), opts.seed);
    let duration_s = core.timeline().duration_s();
    if !duration_s.is_finite() {
        return Err(SimError::Export {
            path: dir.to_path_buf(),
            message: "the scenario never ends (its last segment has no duration-s); a text \
                      export needs a finite scenario"
                .into(),
        });
    }
    std::fs::create_dir_all(dir)?;
    let mut truth = open_truth(opts, &core, dir)?;
    let g0 = imu_model::units::STANDARD_GRAVITY_M_S2;
    let gains = (
        opts.scenario.device.gain_scale.accel,
        opts.scenario.device.gain_scale.gyro,
    );
    let (mut acc, mut gyro) = (String::new(), String::new());
    let rate_hz = opts.scenario.rate_hz;
    let mut samples = 0u64;
    while (samples as f64) / rate_hz <= duration_s {
        let t_s = samples as f64 / rate_hz;
        let (reply, record) = core.data_reply(Command::RawSensorBits, t_s);
        if let Some(w) = truth.as_mut() {
            w.write_sample(&record)?;
        }
        let Reply::RawSensorBits { accel, rate, .. } = reply else {
            unreachable!("a raw-sensor-bits poll gets a raw-sensor-bits reply");
        };
        match units {
            ExportUnits::RawCounts => {
                line(&mut acc, t_s, accel.map(f64::from), 0);
                line(&mut gyro, t_s, rate.map(f64::from), 0);
            }
            ExportUnits::Si => {
                let a = accel.map(|c| scale::raw_bits_to_units(c, gains.0) * g0);
                let w = rate.map(|c| scale::raw_bits_to_units(c, gains.1));
                line(&mut acc, t_s, a, 9);
                line(&mut gyro, t_s, w, 9);
            }
        }
        samples += 1;
    }
    if let Some(w) = truth {
        w.finish()?;
    }
    let (accel_path, gyro_path) = (dir.join("acc.txt"), dir.join("gyro.txt"));
    write_file(&accel_path, &acc)?;
    write_file(&gyro_path, &gyro)?;
    let count = |gain: u16| f64::from(gain) / 32_768_000.0;
    Ok(TextExport {
        accel: accel_path,
        gyro: gyro_path,
        samples,
        accel_count_m_s2: count(gains.0) * g0,
        gyro_count_rad_s: count(gains.1),
    })
}

/// What [`export_parts`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct PartsExport {
    /// The CSV file.
    pub path: PathBuf,
    /// Rows written (the parts' samples).
    pub samples: u64,
    /// The parts in order, with their first row (0-based, data rows) and row count.
    pub parts: Vec<(String, u64, u64)>,
    /// The rate of the rows, Hz (the scenario's rate; the file has no time column).
    pub rate_hz: f64,
    /// One accelerometer count, m/s^2.
    pub accel_count_m_s2: f64,
    /// One gyro count, rad/s (before any negation: a flipped gyro reads with `-` this).
    pub gyro_count_rad_s: f64,
}

/// Runs `opts`'s scenario (which must end) and writes the samples of its parts to `path` as
/// a labelled session without time (the module's doc), the gyro's counts times `gyro_sign`
/// (+1, or -1 for a gyro whose sign is flipped); with `opts.truth_out` the truth of every
/// sample, written or cut.
pub fn export_parts(
    opts: &SimOptions,
    path: &Path,
    gyro_sign: i32,
) -> Result<PartsExport, SimError> {
    let mut core = DeviceCore::new(opts.scenario.clone(), opts.truth.clone(), opts.seed);
    let duration_s = core.timeline().duration_s();
    let bad = |message: &str| SimError::Export {
        path: path.to_path_buf(),
        message: message.into(),
    };
    if !duration_s.is_finite() {
        return Err(bad(
            "the scenario never ends (its last segment has no duration-s); a \
                        text export needs a finite scenario",
        ));
    }
    if gyro_sign.abs() != 1 {
        return Err(bad("the gyro's sign is +1 or -1"));
    }
    let part_of: Vec<Option<String>> = core
        .timeline()
        .segments()
        .iter()
        .map(|s| s.part.clone())
        .collect();
    if part_of.iter().all(Option::is_none) {
        return Err(bad(
            "no segment of the scenario has a `part`: nothing to write",
        ));
    }
    let mut truth = open_truth(opts, &core, path.parent().unwrap_or(Path::new(".")))?;
    let gains = (
        opts.scenario.device.gain_scale.accel,
        opts.scenario.device.gain_scale.gyro,
    );
    let mut out = String::from("part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n");
    let mut parts: Vec<(String, u64, u64)> = Vec::new();
    let rate_hz = opts.scenario.rate_hz;
    let (mut k, mut rows) = (0u64, 0u64);
    let mut current: Option<&str> = None;
    while (k as f64) / rate_hz <= duration_s {
        let (reply, record) = core.data_reply(Command::RawSensorBits, k as f64 / rate_hz);
        k += 1;
        if let Some(w) = truth.as_mut() {
            w.write_sample(&record)?;
        }
        let Some(part) = part_of
            .get(record.segment as usize)
            .and_then(|p| p.as_deref())
        else {
            current = None;
            continue;
        };
        let Reply::RawSensorBits { accel, rate, .. } = reply else {
            unreachable!("a raw-sensor-bits poll gets a raw-sensor-bits reply");
        };
        if current != Some(part) {
            parts.push((part.to_string(), rows, 0));
            current = Some(part);
        }
        let last = parts.last_mut().expect("a part was started");
        let signed = |c: u16| i32::from(c) - 32_768;
        let _ = writeln!(
            out,
            "{part},{},{},{},{},{},{},{}",
            last.2,
            signed(accel[0]),
            signed(accel[1]),
            signed(accel[2]),
            gyro_sign * signed(rate[0]),
            gyro_sign * signed(rate[1]),
            gyro_sign * signed(rate[2]),
        );
        last.2 += 1;
        rows += 1;
    }
    if let Some(w) = truth {
        w.finish()?;
    }
    write_file(path, &out)?;
    let count = |gain: u16| f64::from(gain) / 32_768_000.0;
    Ok(PartsExport {
        path: path.to_path_buf(),
        samples: rows,
        parts,
        rate_hz,
        accel_count_m_s2: count(gains.0) * imu_model::units::STANDARD_GRAVITY_M_S2,
        gyro_count_rad_s: count(gains.1),
    })
}

/// Appends `t x y z` with `decimals` digits after the point for the values.
fn line(out: &mut String, t_s: f64, v: [f64; 3], decimals: usize) {
    let _ = writeln!(
        out,
        "{t_s:.6} {:.decimals$} {:.decimals$} {:.decimals$}",
        v[0], v[1], v[2]
    );
}

fn write_file(path: &Path, text: &str) -> Result<(), SimError> {
    let mut f = std::fs::File::create(path)?;
    f.write_all(text.as_bytes())?;
    f.sync_all()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A still, level, perfect unit at 10 Hz: gravity on -z in counts around 32768 with the
    /// documented scale, zero rate at mid-scale; the same in SI; the truth file holds every
    /// sample exported.
    #[test]
    fn counts_around_mid_scale_and_si() {
        let dir = tempfile::tempdir().unwrap();
        let scenario =
            "name = \"t\"\nrate-hz = 10.0\n[[segment]]\nkind = \"static\"\nduration-s = 2.0\n";
        let path = dir.path().join("s.toml");
        std::fs::write(&path, scenario).unwrap();
        let mut opts = SimOptions::from_files(&path, None).unwrap();
        opts.truth_out = Some(dir.path().join("truth.mcap"));
        let out = export_text(&opts, &dir.path().join("raw"), ExportUnits::RawCounts).unwrap();
        assert_eq!(out.samples, 21);
        let text = std::fs::read_to_string(&out.accel).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 21);
        let g = imu_model::units::STANDARD_GRAVITY_M_S2;
        for (k, r) in rows.iter().enumerate() {
            assert_eq!(r.len(), 4);
            assert!((r[0] - k as f64 * 0.1).abs() < 1e-9);
            assert_eq!(&r[1..3], &[32768.0, 32768.0]);
            let z_m_s2 = (r[3] - 32768.0) * out.accel_count_m_s2;
            assert!((z_m_s2 + g).abs() <= out.accel_count_m_s2, "{z_m_s2}");
        }
        let gyro = std::fs::read_to_string(&out.gyro).unwrap();
        // Earth's rate is under one count.
        assert!(
            gyro.lines().all(|l| l.ends_with(" 32768 32768 32768")),
            "{gyro}"
        );
        let truth = imu_rec::truth::read_truth(&dir.path().join("truth.mcap")).unwrap();
        assert_eq!(truth.samples.len(), 21);

        let si = export_text(&opts, &dir.path().join("si"), ExportUnits::Si).unwrap();
        let first = std::fs::read_to_string(&si.accel).unwrap();
        let z: f64 = first
            .lines()
            .next()
            .unwrap()
            .split_whitespace()
            .nth(3)
            .unwrap()
            .parse()
            .unwrap();
        assert!((z + g).abs() <= out.accel_count_m_s2, "{z}");
    }
}
