//! The arguments the clients share: how to read recordings (`CsvArgs`, feature `analysis`: text
//! units, columns, labels, the gyro's file, the IMU topic), the `--add EFFECT`
//! parser, the one value parser for every float flag ([`finite_f64`]), and telling a closed
//! output pipe (`imu-noise rec.mcap --json | head`) from a real failure.

#[cfg(feature = "analysis")]
pub use csv_args::CsvArgs;

use imu_model::{EffectKind, Triad};

/// Parses an effect named on a command line (`--add`): `triad:effect` (`gyro:g-sensitivity`)
/// or a bare effect id for accel and gyro, wherever it applies. Errors quote `flag` and the
/// spec.
pub fn parse_effect(spec: &str, flag: &str) -> Result<Vec<(Triad, EffectKind)>, String> {
    use std::str::FromStr;
    let (triads, id) = match spec.split_once(':') {
        Some((t, id)) => {
            let t = Triad::from_str(t.trim()).map_err(|e| format!("{flag} {spec}: {e}"))?;
            if t == Triad::Mag {
                return Err(format!(
                    "{flag} {spec}: only accel and gyro models are fitted"
                ));
            }
            (vec![t], id.trim())
        }
        None => (vec![Triad::Accel, Triad::Gyro], spec.trim()),
    };
    let k = EffectKind::from_str(id).map_err(|e| format!("{flag} {spec}: {e}"))?;
    let out: Vec<(Triad, EffectKind)> = triads
        .into_iter()
        .filter(|t| k.applies_to(*t))
        .map(|t| (t, k))
        .collect();
    if out.is_empty() {
        return Err(format!("{flag} {spec}: {id} does not apply to that triad"));
    }
    Ok(out)
}

#[cfg(feature = "analysis")]
mod csv_args {
    use std::path::{Path, PathBuf};

    use imu_analysis::input::{AccelUnit, ColumnRef, Columns, CsvOptions, GyroUnit, InputOptions};

    /// How to read recordings: text units, columns and labels, the gyro's own file, and the
    /// IMU topic of an MCAP file or rosbag2 directory (MCAP recordings carry their own units).
    #[derive(Clone, Debug, clap::Args)]
    pub struct CsvArgs {
        /// Text recordings: seconds per unit of the time column (1 for s, 1e-9 for ns).
        #[arg(long, default_value_t = 1.0, value_name = "S", value_parser = super::finite_f64)]
        pub csv_time_scale_s: f64,
        /// Text recordings without a time column: their sample rate, Hz. The columns are then
        /// ax, ay, az, gx, gy, gz (ax, ay, az with --gyro-csv, whose rows are at the same rate)
        /// and data row n is at --start-s + n / R, across all parts of a labelled session (a
        /// per-part sample index is then just a column that is not read).
        #[arg(long, value_name = "R", value_parser = super::positive_f64,
              conflicts_with = "csv_time_scale_s")]
        pub rate_hz: Option<f64>,
        /// With --rate-hz: the time of a file's first row, s (orders the files of a session).
        #[arg(long, default_value_t = 0.0, value_name = "S", value_parser = super::finite_f64,
              requires = "rate_hz")]
        pub start_s: f64,
        /// Text recordings: unit of the accelerometer columns: m/s2, g, or
        /// counts:SCALE[@OFFSET] (raw counts less OFFSET, times SCALE m/s^2 per count; SCALE and
        /// OFFSET each one number or X,Y,Z, e.g. counts:0.00241@32768 for unsigned 16-bit
        /// counts with mid-scale zero).
        #[arg(long, default_value = "m/s2", value_name = "UNIT")]
        pub csv_accel: AccelUnit,
        /// Text recordings: unit of the gyro columns: rad/s, deg/s, or counts:SCALE[@OFFSET]
        /// (rad/s per count; as for --csv-accel).
        #[arg(long, default_value = "rad/s", value_name = "UNIT")]
        pub csv_gyro: GyroUnit,
        /// The gyro's own text file (`time, gx, gy, gz`, on the accelerometer's clock, any
        /// layout) for a text recording that holds only the accelerometer (`time, ax, ay, az`);
        /// with several text recordings, one per recording, in order.
        #[arg(long = "gyro-csv", value_name = "GYRO.txt")]
        pub gyro_csv: Vec<PathBuf>,
        /// Text recordings: the columns of time, ax, ay, az, gx, gy, gz (time, ax, ay, az with
        /// --gyro-csv; no time with --rate-hz), each a 0-based index (the first column is 0) or a name from the header
        /// line, e.g. `--columns t,ax,ay,az,gx,gy,gz` or `--columns 0,4,5,6,1,2,3`. Default: the
        /// first columns in that order, a label column left out.
        #[arg(long, value_name = "[T,]AX,AY,AZ[,GX,GY,GZ]", value_delimiter = ',')]
        pub columns: Vec<ColumnRef>,
        /// The --gyro-csv file's columns of time, gx, gy, gz (no time with --rate-hz; 0-based
        /// indices or header names).
        #[arg(
            long,
            value_name = "[T,]GX,GY,GZ",
            value_delimiter = ',',
            requires = "gyro_csv"
        )]
        pub gyro_columns: Vec<ColumnRef>,
        /// Text recordings: the column naming the part of a labelled session each sample
        /// belongs to (0-based index or header name). Default: a header column named `part` or
        /// `label`, if any.
        #[arg(long, value_name = "COLUMN")]
        pub label_column: Option<ColumnRef>,
        /// The sensor_msgs/msg/Imu topic to read when an MCAP file or rosbag2 directory has
        /// several (without it, several are an error that lists them).
        #[arg(long, value_name = "TOPIC")]
        pub topic: Option<String>,
    }

    /// A text recording, told by content: not a directory and no MCAP magic bytes (a file
    /// that cannot be opened goes by its extension; reading it will say why it cannot be).
    fn is_text(p: &Path) -> bool {
        if p.is_dir() {
            return false;
        }
        match imu_rec::mcap_read::has_mcap_magic(p) {
            Ok(mcap) => !mcap,
            Err(_) => p.extension().and_then(|e| e.to_str()) != Some("mcap"),
        }
    }

    impl CsvArgs {
        /// The reading options of `recordings[k]`: the units, and its gyro file when
        /// `--gyro-csv` was given (the k-th text recording takes the k-th file).
        pub fn options_for(&self, recordings: &[PathBuf], k: usize) -> Result<CsvOptions, String> {
            let csv: Vec<usize> = (0..recordings.len())
                .filter(|&i| is_text(&recordings[i]))
                .collect();
            let gyro_file = if self.gyro_csv.is_empty() {
                None
            } else if self.gyro_csv.len() != csv.len() {
                return Err(format!(
                    "{} --gyro-csv file(s) for {} CSV recording(s): give one gyro file per \
                     accelerometer-only CSV recording, in order",
                    self.gyro_csv.len(),
                    csv.len()
                ));
            } else {
                csv.iter()
                    .position(|&i| i == k)
                    .map(|n| self.gyro_csv[n].clone())
            };
            Ok(CsvOptions {
                time_scale_s: self.csv_time_scale_s,
                rate_hz: self.rate_hz,
                start_s: self.start_s,
                accel: self.csv_accel,
                gyro: self.csv_gyro,
                gyro_file,
            })
        }

        /// Everything needed to read `recordings[k]` (one file, the files of one session or a
        /// directory) from `source`: [`CsvArgs::options_for`], the columns and the topic.
        pub fn input_options(
            &self,
            recordings: &[PathBuf],
            k: usize,
            source: imu_analysis::Source,
        ) -> Result<InputOptions, String> {
            let list = |v: &[ColumnRef]| (!v.is_empty()).then(|| v.to_vec());
            Ok(InputOptions {
                source,
                csv: self.options_for(recordings, k)?,
                columns: Columns {
                    main: list(&self.columns),
                    gyro: list(&self.gyro_columns),
                    label: self.label_column.clone(),
                },
                topic: self.topic.clone(),
            })
        }
    }
}

/// The value parser of every float flag: a number, refused at parse time when it is NaN or
/// infinite (`--csv-time-scale-s nan` is a usage error, not a silently empty analysis).
pub fn finite_f64(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|e| format!("`{s}` is not a number: {e}"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("`{s}` is not a finite number"))
    }
}

/// The value parser of a rate: a finite number above zero.
pub fn positive_f64(s: &str) -> Result<f64, String> {
    let v = finite_f64(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("`{s}` is not above zero"))
    }
}

/// True if any error in `chain` (an error and its sources) is an I/O error of kind
/// `BrokenPipe`, directly or inside a JSON writer's error: the reader went away, which is not
/// the tool's failure.
pub fn is_broken_pipe<'a>(
    mut chain: impl Iterator<Item = &'a (dyn std::error::Error + 'static)>,
) -> bool {
    chain.any(|c| {
        c.downcast_ref::<std::io::Error>()
            .map(std::io::Error::kind)
            .or_else(|| {
                c.downcast_ref::<serde_json::Error>()
                    .and_then(serde_json::Error::io_error_kind)
            })
            == Some(std::io::ErrorKind::BrokenPipe)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_flags_refuse_nan_and_infinities() {
        assert_eq!(finite_f64("1e-9"), Ok(1e-9));
        assert_eq!(finite_f64(" -2.5 "), Ok(-2.5));
        for bad in ["nan", "NaN", "inf", "-inf", "infinity", "1e999", "x"] {
            assert!(finite_f64(bad).is_err(), "{bad} accepted");
            assert!(positive_f64(bad).is_err(), "{bad} accepted");
        }
        assert_eq!(positive_f64("204.8"), Ok(204.8));
        assert!(positive_f64("0").is_err() && positive_f64("-100").is_err());
    }

    /// `--rate-hz` reaches the text reader's options with `--start-s`; `--start-s` alone, a
    /// rate with a time scale, and a rate that is not above zero are usage errors.
    #[cfg(feature = "analysis")]
    #[test]
    fn a_rate_times_text_without_a_time_column() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            csv: CsvArgs,
        }
        let parse = |args: &[&str]| Cli::try_parse_from([&["tool"], args].concat());
        let cli = parse(&["--rate-hz", "204.8", "--start-s", "12.5"]).unwrap();
        let o = cli.csv.options_for(&[], 0).unwrap();
        assert_eq!((o.rate_hz, o.start_s), (Some(204.8), 12.5));
        assert_eq!(
            parse(&[]).unwrap().csv.options_for(&[], 0).unwrap().rate_hz,
            None
        );
        for bad in [
            &["--start-s", "1"][..],
            &["--rate-hz", "100", "--csv-time-scale-s", "1e-9"],
            &["--rate-hz", "0"],
            &["--rate-hz", "-5"],
        ] {
            assert!(parse(bad).is_err(), "{bad:?} accepted");
        }
    }

    #[derive(Debug, thiserror::Error)]
    #[error("writing the table")]
    struct Wrapper(#[source] std::io::Error);

    #[test]
    fn broken_pipes_are_found_through_sources_and_json() {
        let io = || std::io::Error::from(std::io::ErrorKind::BrokenPipe);
        let w = Wrapper(io());
        let chain = || {
            std::iter::successors(Some(&w as &(dyn std::error::Error + 'static)), |e| {
                e.source()
            })
        };
        assert!(is_broken_pipe(chain()));
        let j = serde_json::Error::io(io());
        assert!(is_broken_pipe(std::iter::once(
            &j as &(dyn std::error::Error + 'static)
        )));
        let other = Wrapper(std::io::Error::from(std::io::ErrorKind::NotFound));
        assert!(!is_broken_pipe(std::iter::once(
            &other as &(dyn std::error::Error + 'static)
        )));
    }
}
