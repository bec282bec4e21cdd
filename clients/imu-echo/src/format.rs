//! The three output formats of imu-echo (table, csv, jsonl) for each shared-memory payload.

use std::io::{self, Write};
use std::marker::PhantomData;

use imu_bus::sample::{device_protocol, health_state, time_source, time_sync};
use imu_bus::shm::ShmPayload;
use imu_bus::{CalibrationHealth, CorrectedSample, DaemonStatus, RawSample};

use crate::Format;

/// One value of a row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Cell {
    /// An unsigned integer.
    U(u64),
    /// A signed integer.
    I(i64),
    /// A float shown with `prec` decimals in the table (full precision in csv).
    F { value: f64, prec: usize },
    /// A time in ns: seconds with 6 decimals in the table, integer ns in csv.
    Ns(u64),
    /// Bits or ids: hexadecimal in the table, decimal in csv.
    Hex(u64),
    /// A word (a state's name).
    Text(&'static str),
}

/// One column: its csv name (the field name, with its unit), its table header and width.
#[derive(Debug, Clone, Copy)]
pub struct Column {
    /// Header in csv: snake_case with the unit, e.g. `accel_x_m_s2`.
    pub csv: &'static str,
    /// Header in the table, e.g. `ax[m/s2]`.
    pub table: &'static str,
    /// Table column width in characters.
    pub width: usize,
}

const fn col(csv: &'static str, table: &'static str, width: usize) -> Column {
    Column { csv, table, width }
}

/// A payload imu-echo can print.
pub trait Echo: ShmPayload + serde::Serialize {
    /// Whether the type has a `seq` (and so a missed-sample count).
    const HAS_SEQ: bool;
    /// The columns of the table and csv formats.
    const COLUMNS: &'static [Column];
    /// Appends this sample's cells, one per column.
    fn cells(&self, out: &mut Vec<Cell>);
}

fn floats(out: &mut Vec<Cell>, values: &[f64], prec: usize) {
    out.extend(values.iter().map(|&value| Cell::F { value, prec }));
}

fn ints(out: &mut Vec<Cell>, values: &[i32]) {
    out.extend(values.iter().map(|&v| Cell::I(v.into())));
}

impl Echo for CorrectedSample {
    const HAS_SEQ: bool = true;
    const COLUMNS: &'static [Column] = &[
        col("seq", "seq", 9),
        col("t_sample_ns", "t_sample[s]", 16),
        col("accel_x_m_s2", "ax[m/s2]", 10),
        col("accel_y_m_s2", "ay[m/s2]", 10),
        col("accel_z_m_s2", "az[m/s2]", 10),
        col("gyro_x_rad_s", "gx[rad/s]", 10),
        col("gyro_y_rad_s", "gy[rad/s]", 10),
        col("gyro_z_rad_s", "gz[rad/s]", 10),
        col("mag_x_gauss", "mx[G]", 8),
        col("mag_y_gauss", "my[G]", 8),
        col("mag_z_gauss", "mz[G]", 8),
        col("temp_c", "temp[C]", 8),
        col("calibration_id", "calibration", 18),
        col("flags", "flags", 6),
    ];

    fn cells(&self, out: &mut Vec<Cell>) {
        out.push(Cell::U(self.seq));
        out.push(Cell::Ns(self.t_sample_ns));
        floats(out, &self.accel_m_s2, 4);
        floats(out, &self.gyro_rad_s, 5);
        floats(out, &self.mag_gauss, 4);
        floats(out, &[self.temp_c], 2);
        out.push(Cell::Hex(self.calibration_id));
        out.push(Cell::Hex(self.flags.into()));
    }
}

impl Echo for RawSample {
    const HAS_SEQ: bool = true;
    const COLUMNS: &'static [Column] = &[
        col("seq", "seq", 9),
        col("t_sample_ns", "t_sample[s]", 16),
        col("ticks", "ticks", 6),
        col("accel_x_counts", "ax[cnt]", 8),
        col("accel_y_counts", "ay[cnt]", 8),
        col("accel_z_counts", "az[cnt]", 8),
        col("gyro_x_counts", "gx[cnt]", 8),
        col("gyro_y_counts", "gy[cnt]", 8),
        col("gyro_z_counts", "gz[cnt]", 8),
        col("mag_x_counts", "mx[cnt]", 8),
        col("mag_y_counts", "my[cnt]", 8),
        col("mag_z_counts", "mz[cnt]", 8),
        col("accel_x_device_m_s2", "ax[m/s2]", 9),
        col("accel_y_device_m_s2", "ay[m/s2]", 9),
        col("accel_z_device_m_s2", "az[m/s2]", 9),
        col("gyro_x_device_rad_s", "gx[rad/s]", 10),
        col("gyro_y_device_rad_s", "gy[rad/s]", 10),
        col("gyro_z_device_rad_s", "gz[rad/s]", 10),
        col("temp_c", "temp[C]", 8),
        col("command", "cmd", 5),
        col("flags", "flags", 6),
    ];

    fn cells(&self, out: &mut Vec<Cell>) {
        out.push(Cell::U(self.seq));
        out.push(Cell::Ns(self.t_sample_ns));
        out.push(Cell::U(self.ticks.into()));
        ints(out, &self.accel_counts);
        ints(out, &self.gyro_counts);
        ints(out, &self.mag_counts);
        floats(out, &self.accel_device_m_s2, 4);
        floats(out, &self.gyro_device_rad_s, 5);
        floats(out, &[self.temp_c], 2);
        out.push(Cell::Hex(self.command.into()));
        out.push(Cell::Hex(self.flags.into()));
    }
}

impl Echo for DaemonStatus {
    const HAS_SEQ: bool = false;
    const COLUMNS: &'static [Column] = &[
        col("t_host_monotonic_ns", "t_host[s]", 16),
        col("frames", "frames", 9),
        col("samples", "samples", 9),
        col("checksum_failures", "cksum_fail", 10),
        col("resyncs", "resyncs", 8),
        col("garbage_bytes", "garbage[B]", 10),
        col("truncated_frames", "truncated", 9),
        col("samples_lost", "lost", 7),
        col("log_drops", "log_drops", 9),
        col("publish_drops", "pub_drops", 9),
        col("reconnects", "reconnects", 10),
        col("calibration_id", "calibration", 18),
        col("tick_period_est_s", "tick[s]", 11),
        col("clock_drift_ppm", "drift[ppm]", 10),
        col("temp_c", "temp[C]", 8),
        col("device_connected", "device", 6),
        col("logging", "logging", 7),
        col("health_accel", "accel", 12),
        col("health_gyro", "gyro", 12),
        col("protocol", "protocol", 8),
        col("configuration_unverified", "unverified", 10),
        col("packets_unusable", "unusable", 8),
        col("fields_skipped", "skipped", 8),
        col("time_source", "time_src", 8),
        col("time_sync", "time_sync", 13),
        col("gnss_minus_wall_s", "gnss-wall[s]", 12),
        col("gnss_drift_ppm", "gnss_drift[ppm]", 15),
        col("gnss_valid_transitions", "gnss_valid", 10),
        col("gnss_lost_transitions", "gnss_lost", 9),
    ];

    fn cells(&self, out: &mut Vec<Cell>) {
        out.push(Cell::Ns(self.t_host_monotonic_ns));
        out.extend(
            [
                self.frames,
                self.samples,
                self.checksum_failures,
                self.resyncs,
                self.garbage_bytes,
                self.truncated_frames,
                self.samples_lost,
                self.log_drops,
                self.publish_drops,
                self.reconnects,
            ]
            .map(Cell::U),
        );
        out.push(Cell::Hex(self.calibration_id));
        floats(out, &[self.tick_period_est_s], 9);
        floats(out, &[self.clock_drift_ppm], 3);
        floats(out, &[self.temp_c], 2);
        out.push(Cell::U(self.device_connected.into()));
        out.push(Cell::U(self.logging.into()));
        out.push(Cell::Text(health_state::name(self.health_accel)));
        out.push(Cell::Text(health_state::name(self.health_gyro)));
        out.push(Cell::Text(match self.protocol {
            device_protocol::MIP => "mip",
            device_protocol::VECTORNAV => "vectornav",
            device_protocol::ROS2_INPUT => "ros2-input",
            device_protocol::XSENS => "xsens",
            _ => "3dm-gx1",
        }));
        out.push(Cell::U(self.configuration_unverified.into()));
        out.push(Cell::U(self.packets_unusable));
        out.push(Cell::U(self.fields_skipped));
        out.push(Cell::Text(time_source::name(self.time_source)));
        out.push(Cell::Text(time_sync::name(self.time_sync)));
        floats(out, &[self.gnss_minus_wall_s], 6);
        floats(out, &[self.gnss_drift_ppm], 3);
        out.push(Cell::U(self.gnss_valid_transitions));
        out.push(Cell::U(self.gnss_lost_transitions));
    }
}

impl Echo for CalibrationHealth {
    const HAS_SEQ: bool = false;
    const COLUMNS: &'static [Column] = &[
        col("t_sample_ns", "t_end[s]", 16),
        col("window_s", "window[s]", 9),
        col("accel_state", "accel", 12),
        col("gyro_state", "gyro", 12),
        col("accel_residual_m_s2", "|f|-g[m/s2]", 11),
        col("accel_expected_std_m_s2", "+-[m/s2]", 9),
        col("accel_p", "p_accel", 9),
        col("gyro_residual_rad_s", "|w|-W[rad/s]", 12),
        col("gyro_expected_std_rad_s", "+-[rad/s]", 9),
        col("gyro_p", "p_gyro", 9),
        col("accel_offset_x_m_s2", "dax[m/s2]", 10),
        col("accel_offset_y_m_s2", "day[m/s2]", 10),
        col("accel_offset_z_m_s2", "daz[m/s2]", 10),
        col("gyro_offset_x_rad_s", "dgx[rad/s]", 10),
        col("gyro_offset_y_rad_s", "dgy[rad/s]", 10),
        col("gyro_offset_z_rad_s", "dgz[rad/s]", 10),
        col("temp_c", "temp[C]", 8),
        col("still_windows", "windows", 8),
        col("checks", "checks", 6),
    ];

    fn cells(&self, out: &mut Vec<Cell>) {
        out.push(Cell::Ns(self.t_sample_ns));
        let window_s = self.t_sample_ns.saturating_sub(self.window_start_ns) as f64 * 1e-9;
        floats(out, &[window_s], 1);
        out.push(Cell::Text(health_state::name(self.accel_state)));
        out.push(Cell::Text(health_state::name(self.gyro_state)));
        floats(
            out,
            &[self.accel_residual_m_s2, self.accel_expected_std_m_s2],
            5,
        );
        floats(out, &[self.accel_p], 4);
        floats(
            out,
            &[self.gyro_residual_rad_s, self.gyro_expected_std_rad_s],
            6,
        );
        floats(out, &[self.gyro_p], 4);
        floats(out, &self.accel_offset_m_s2, 5);
        floats(out, &self.gyro_offset_rad_s, 6);
        floats(out, &[self.temp_c], 2);
        out.push(Cell::U(self.still_windows));
        out.push(Cell::Hex(self.checks.into()));
    }
}

/// Writes the header and rows of one format; reuses its cell buffer across rows.
pub struct Printer<T: Echo> {
    format: Format,
    cells: Vec<Cell>,
    _payload: PhantomData<T>,
}

impl<T: Echo> Printer<T> {
    /// A printer for `format`.
    pub fn new(format: Format) -> Self {
        Printer {
            format,
            cells: Vec::with_capacity(T::COLUMNS.len()),
            _payload: PhantomData,
        }
    }

    /// The header line (table and csv; nothing for jsonl).
    pub fn header(&self, w: &mut impl Write) -> io::Result<()> {
        match self.format {
            Format::Table => {
                let mut first = true;
                for c in T::COLUMNS {
                    if !first {
                        w.write_all(b" ")?;
                    }
                    first = false;
                    write!(w, "{:>width$}", c.table, width = c.width)?;
                }
                writeln!(w)
            }
            Format::Csv => {
                let names: Vec<&str> = T::COLUMNS.iter().map(|c| c.csv).collect();
                writeln!(w, "{}", names.join(","))
            }
            Format::Jsonl => Ok(()),
        }
    }

    /// One sample.
    pub fn row(&mut self, w: &mut impl Write, sample: &T) -> io::Result<()> {
        match self.format {
            Format::Jsonl => {
                serde_json::to_writer(&mut *w, sample)?;
                writeln!(w)
            }
            Format::Table | Format::Csv => {
                self.cells.clear();
                sample.cells(&mut self.cells);
                debug_assert_eq!(self.cells.len(), T::COLUMNS.len());
                for (i, (cell, column)) in self.cells.iter().zip(T::COLUMNS).enumerate() {
                    if self.format == Format::Table {
                        if i > 0 {
                            w.write_all(b" ")?;
                        }
                        write_table_cell(w, *cell, column.width)?;
                    } else {
                        if i > 0 {
                            w.write_all(b",")?;
                        }
                        write_csv_cell(w, *cell)?;
                    }
                }
                writeln!(w)
            }
        }
    }
}

fn write_table_cell(w: &mut impl Write, cell: Cell, width: usize) -> io::Result<()> {
    match cell {
        Cell::U(v) => write!(w, "{v:>width$}"),
        Cell::I(v) => write!(w, "{v:>width$}"),
        Cell::F { value, prec } if needs_exponent(value, 1e7, 0.5 * 10f64.powi(-(prec as i32))) => {
            write!(w, "{value:>width$.3e}")
        }
        Cell::F { value, prec } => write!(w, "{value:>width$.prec$}"),
        Cell::Ns(ns) => write!(w, "{:>width$.6}", ns as f64 * 1e-9),
        Cell::Hex(v) => write!(w, "{:>width$}", format!("{v:#x}")),
        Cell::Text(s) => write!(w, "{s:>width$}"),
    }
}

/// Whether `value` is too large or too small (but not zero) for fixed-point notation.
fn needs_exponent(value: f64, large: f64, small: f64) -> bool {
    value.is_finite() && value != 0.0 && (value.abs() >= large || value.abs() < small)
}

fn write_csv_cell(w: &mut impl Write, cell: Cell) -> io::Result<()> {
    match cell {
        Cell::U(v) | Cell::Ns(v) | Cell::Hex(v) => write!(w, "{v}"),
        Cell::I(v) => write!(w, "{v}"),
        // `{}` and `{:e}` of an f64 are the shortest texts that parse back to the same value;
        // `{}` never uses an exponent, which would spell out 1e-300 in 300 digits.
        Cell::F { value, .. } if needs_exponent(value, 1e16, 1e-6) => write!(w, "{value:e}"),
        Cell::F { value, .. } => write!(w, "{value}"),
        Cell::Text(s) => w.write_all(s.as_bytes()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corrected() -> CorrectedSample {
        CorrectedSample {
            seq: 12,
            t_sample_ns: 1_500_000_000,
            accel_m_s2: [0.1, -9.80665, 0.0],
            gyro_rad_s: [0.001, 0.0, -0.002],
            mag_gauss: [0.2, 0.3, -0.4],
            temp_c: f64::NAN,
            calibration_id: 0xabc,
            flags: 1,
            ..Default::default()
        }
    }

    fn render<T: Echo>(format: Format, samples: &[T]) -> String {
        let mut p = Printer::<T>::new(format);
        let mut buf = Vec::new();
        p.header(&mut buf).unwrap();
        for s in samples {
            p.row(&mut buf, s).unwrap();
        }
        String::from_utf8(buf).unwrap()
    }

    #[test]
    fn every_type_has_one_cell_per_column() {
        let mut cells = Vec::new();
        CorrectedSample::default().cells(&mut cells);
        assert_eq!(cells.len(), CorrectedSample::COLUMNS.len());
        cells.clear();
        RawSample::default().cells(&mut cells);
        assert_eq!(cells.len(), RawSample::COLUMNS.len());
        cells.clear();
        DaemonStatus::default().cells(&mut cells);
        assert_eq!(cells.len(), DaemonStatus::COLUMNS.len());
        cells.clear();
        CalibrationHealth::default().cells(&mut cells);
        assert_eq!(cells.len(), CalibrationHealth::COLUMNS.len());
    }

    #[test]
    fn csv_has_a_header_with_units_and_full_precision_rows() {
        let text = render(Format::Csv, &[corrected()]);
        let mut lines = text.lines();
        let header = lines.next().unwrap();
        assert!(
            header.starts_with("seq,t_sample_ns,accel_x_m_s2,"),
            "{header}"
        );
        assert_eq!(
            lines.next().unwrap(),
            "12,1500000000,0.1,-9.80665,0,0.001,0,-0.002,0.2,0.3,-0.4,NaN,2748,1"
        );
        assert!(lines.next().is_none());
    }

    #[test]
    fn table_columns_line_up_with_the_header() {
        let text = render(Format::Table, &[corrected(), corrected()]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[0].contains("ax[m/s2]") && lines[0].contains("gx[rad/s]"));
        assert!(lines.iter().all(|l| l.len() == lines[0].len()), "{text}");
        assert!(lines[1].contains("1.500000") && lines[1].contains("-9.8066"));
    }

    #[test]
    fn extreme_floats_use_an_exponent_and_round_trip_in_csv() {
        let s = CorrectedSample {
            gyro_rad_s: [1e-300, f64::MAX, -0.0],
            ..corrected()
        };
        let csv = render(Format::Csv, &[s]);
        let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
        assert_eq!(row[5..8], ["1e-300", "1.7976931348623157e308", "-0"]);
        assert_eq!(row[5].parse::<f64>().unwrap(), 1e-300);
        let table = render(Format::Table, &[s]);
        assert!(
            table.contains("1.000e-300") && table.contains("1.798e308"),
            "{table}"
        );
        let lines: Vec<&str> = table.lines().collect();
        assert!(lines[1].len() < 2 * lines[0].len(), "{table}");
    }

    #[test]
    fn jsonl_uses_the_field_names_with_units() {
        let text = render(Format::Jsonl, &[corrected()]);
        let v: serde_json::Value = serde_json::from_str(text.trim_end()).unwrap();
        assert_eq!(v["seq"], 12);
        assert_eq!(v["accel_m_s2"][1], -9.80665);
        assert!(v["temp_c"].is_null(), "NaN becomes null");
        let status = render(Format::Jsonl, &[DaemonStatus::default()]);
        assert!(status.contains("\"publish_drops\":0"), "{status}");
    }

    #[test]
    fn a_passive_units_status_says_its_configuration_was_not_verified() {
        let passive = DaemonStatus {
            configuration_unverified: 1,
            ..DaemonStatus::default()
        };
        for (status, want) in [(passive, "1"), (DaemonStatus::default(), "0")] {
            let csv = render(Format::Csv, &[status]);
            let mut lines = csv.lines();
            let header: Vec<&str> = lines.next().unwrap().split(',').collect();
            let row: Vec<&str> = lines.next().unwrap().split(',').collect();
            let i = header
                .iter()
                .position(|&h| h == "configuration_unverified")
                .expect("a column");
            assert_eq!(row[i], want, "{csv}");
            let table = render(Format::Table, &[status]);
            assert!(table.lines().next().unwrap().contains("unverified"));
        }
    }
}
