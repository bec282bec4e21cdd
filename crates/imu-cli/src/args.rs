//! The arguments the clients share: how to read CSV recordings (`CsvArgs`, feature `analysis`), the `--add EFFECT`
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

    use imu_analysis::input::{AccelUnit, CsvOptions, GyroUnit};

    /// How to read CSV recordings (MCAP recordings carry their own units).
    #[derive(Clone, Debug, clap::Args)]
    pub struct CsvArgs {
        /// CSV recordings: seconds per unit of the time column (1 for s, 1e-9 for ns).
        #[arg(long, default_value_t = 1.0, value_name = "S", value_parser = super::finite_f64)]
        pub csv_time_scale_s: f64,
        /// CSV recordings: unit of the accelerometer columns: m/s2, g, or counts:SCALE (raw
        /// counts times SCALE m/s^2 per count).
        #[arg(long, default_value = "m/s2", value_name = "UNIT")]
        pub csv_accel: AccelUnit,
        /// CSV recordings: unit of the gyro columns: rad/s, deg/s, or counts:SCALE (rad/s per
        /// count).
        #[arg(long, default_value = "rad/s", value_name = "UNIT")]
        pub csv_gyro: GyroUnit,
        /// The gyro's own CSV file (`time, gx, gy, gz`, on the accelerometer's clock) for a CSV
        /// recording that holds only the accelerometer (`time, ax, ay, az`); with several CSV
        /// recordings, one per recording, in order.
        #[arg(long = "gyro-csv", value_name = "GYRO.csv")]
        pub gyro_csv: Vec<PathBuf>,
    }

    fn is_csv(p: &Path) -> bool {
        matches!(
            p.extension().and_then(|e| e.to_str()),
            Some("csv") | Some("txt")
        )
    }

    impl CsvArgs {
        /// The reading options of `recordings[k]`: the units, and its gyro file when
        /// `--gyro-csv` was given (the k-th CSV recording takes the k-th file).
        pub fn options_for(&self, recordings: &[PathBuf], k: usize) -> Result<CsvOptions, String> {
            let csv: Vec<usize> = (0..recordings.len())
                .filter(|&i| is_csv(&recordings[i]))
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
                accel: self.csv_accel,
                gyro: self.csv_gyro,
                gyro_file,
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
