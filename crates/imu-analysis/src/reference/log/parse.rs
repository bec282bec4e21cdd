//! Reading a reference log: its columns and units from the header, settings lines, rows read
//! line by line with errors that name the file, line and column.

use super::*;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Column {
    Time(f64),
    Rate(usize, f64),
    Force(usize, f64),
    /// The table's rate about its axis.
    TableRate(f64),
}

pub(super) const COLUMNS: [&str; 17] = [
    "t_s",
    "t_ms",
    "t_ns",
    "wx_rad_s",
    "wy_rad_s",
    "wz_rad_s",
    "wx_deg_s",
    "wy_deg_s",
    "wz_deg_s",
    "fx_m_s2",
    "fy_m_s2",
    "fz_m_s2",
    "fx_g",
    "fy_g",
    "fz_g",
    "rate_deg_s",
    "rate_rad_s",
];

/// Settings a comment line may give (`# key = value`).
pub(super) const SETTINGS: [&str; 3] = ["table-axis", "gravity-m-s2", "latitude-deg"];

pub(super) fn column(name: &str) -> Option<Column> {
    let axis = |c: char| "xyz".find(c);
    Some(match name {
        "t_s" => Column::Time(1.0),
        "t_ms" => Column::Time(1e-3),
        "t_ns" => Column::Time(1e-9),
        "rate_deg_s" => Column::TableRate(DEG_TO_RAD),
        "rate_rad_s" => Column::TableRate(1.0),
        _ => {
            let mut ch = name.chars();
            let (kind, a) = (ch.next()?, axis(ch.next()?)?);
            match (kind, ch.as_str()) {
                ('w', "_rad_s") => Column::Rate(a, 1.0),
                ('w', "_deg_s") => Column::Rate(a, DEG_TO_RAD),
                ('f', "_m_s2") => Column::Force(a, 1.0),
                ('f', "_g") => Column::Force(a, STANDARD_GRAVITY_M_S2),
                _ => return None,
            }
        }
    })
}

/// Example header of a three-axis log, quoted in messages.
const EXAMPLE: &str = "t_s,wx_deg_s,wy_deg_s,wz_deg_s[,fx_m_s2,fy_m_s2,fz_m_s2]";
/// Example opening of a rate table's one-column log, quoted in messages.
const TABLE_EXAMPLE: &str = "# table-axis = +z, then t_s,rate_deg_s";

/// A parse error at `line` of `file`.
fn csv_error(file: &str, line: usize, message: String) -> ReferenceLogError {
    ReferenceLogError::Csv {
        file: file.to_string(),
        line,
        message,
    }
}

/// Settings read from comment lines (`# key = value`), each with the line that gave it.
#[derive(Default)]
struct LogSettings {
    /// The latest table axis, which applies to the rows after it.
    axis: Option<Vec3>,
    /// The table axis of each row read with a table rate column.
    axis_rows: Vec<[f64; 3]>,
    /// (line, rows before it, axis) of each `table-axis` line.
    axis_lines: Vec<(usize, usize, [f64; 3])>,
    /// (line, value) of `gravity-m-s2`.
    gravity: Option<(usize, f64)>,
    /// (line, value) of `latitude-deg`.
    latitude: Option<(usize, f64)>,
    /// The line of the first setting.
    first_setting: Option<usize>,
}

impl LogSettings {
    /// Reads the comment `comment` (after `#`) of line `n`, `rows` rows into the log: a known
    /// setting is checked and kept, a misspelt one is an error, any other comment is skipped.
    fn read_comment(
        &mut self,
        comment: &str,
        n: usize,
        rows: usize,
        file: &str,
    ) -> Result<(), ReferenceLogError> {
        let err = |line: usize, message: String| csv_error(file, line, message);
        let Some((key, value)) = comment.split_once('=') else {
            return Ok(());
        };
        let key = key.trim().to_ascii_lowercase().replace('_', "-");
        let value = value.trim();
        if !SETTINGS.contains(&key.as_str()) {
            let hint = did_you_mean(&key, &SETTINGS);
            if !hint.is_empty() && !key.contains(' ') {
                return Err(err(
                    n,
                    format!(
                        "unknown setting `{key}`{hint}; settings: {}",
                        SETTINGS.join(", ")
                    ),
                ));
            }
            return Ok(());
        }
        self.first_setting.get_or_insert(n);
        let number = || {
            value
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| err(n, format!("{key}: `{value}` is not a number")))
        };
        match key.as_str() {
            "table-axis" => {
                let a = parse_direction(value).ok_or_else(|| {
                    err(
                        n,
                        format!(
                            "table-axis: `{value}` is not a sensor direction: write x, \
                             -x, +y, ..., -z or a vector [x, y, z]"
                        ),
                    )
                })?;
                self.axis = Some(a);
                self.axis_lines.push((n, rows, a.into()));
            }
            "gravity-m-s2" => {
                let g = number()?;
                if !(9.7..=9.9).contains(&g) {
                    return Err(err(
                        n,
                        format!(
                            "gravity-m-s2: {g} is not a gravity on Earth's surface (9.78..9.83)"
                        ),
                    ));
                }
                if let Some((l, _)) = self.gravity.replace((n, g)) {
                    return Err(err(n, format!("gravity-m-s2 is given twice (line {l})")));
                }
            }
            _ => {
                let lat = number()?;
                if !(-90.0..=90.0).contains(&lat) {
                    return Err(err(n, format!("latitude-deg: {lat} is outside -90..90")));
                }
                if let Some((l, _)) = self.latitude.replace((n, lat)) {
                    return Err(err(n, format!("latitude-deg is given twice (line {l})")));
                }
            }
        }
        Ok(())
    }

    /// The table part of the log once every row is read: `None` for a three-axis log (an error
    /// if it gave settings), else the axes, gravity and latitude of a table log.
    fn into_table(self, file: &str) -> Result<Option<TableLog>, ReferenceLogError> {
        if self.axis_rows.is_empty()
            && let Some(l) = self.first_setting
        {
            return Err(csv_error(
                file,
                l,
                format!(
                    "the settings {} apply to a rate table's one-column log (rate_deg_s or \
                     rate_rad_s); this log gives the three axes",
                    SETTINGS.join(", ")
                ),
            ));
        }
        if self.axis_rows.is_empty() {
            return Ok(None);
        }
        let latitude_deg = self.latitude.map(|(_, l)| l);
        let (gravity_m_s2, gravity_source) = match (self.gravity, latitude_deg) {
            (Some((_, g)), _) => (g, format!("{g} m/s^2 (given in the log)")),
            (None, Some(lat)) => {
                let g = normal_gravity_m_s2(lat, 0.0);
                (
                    g,
                    format!("{g:.5} m/s^2 (WGS-84 normal gravity at latitude {lat} deg)"),
                )
            }
            (None, None) => (
                STANDARD_GRAVITY_M_S2,
                format!(
                    "{STANDARD_GRAVITY_M_S2} m/s^2 (standard gravity: give `# gravity-m-s2 \
                     = G` or `# latitude-deg = L` in the log for the local value)"
                ),
            ),
        };
        Ok(Some(TableLog {
            axis_sensor: self.axis_rows,
            axis_lines: self.axis_lines,
            gravity_m_s2,
            gravity_source,
            latitude_deg,
        }))
    }
}

/// Reads the header line `n`: its columns, and whether it gives the three specific force
/// columns. Checks each name, repeats, and the set (time plus three rates or one table rate).
fn parse_header(
    fields: &[&str],
    n: usize,
    file: &str,
) -> Result<(Vec<Column>, bool), ReferenceLogError> {
    let err = |line: usize, message: String| csv_error(file, line, message);
    let mut cols = Vec::new();
    for f in fields {
        let name = f.to_ascii_lowercase();
        let c = column(&name).ok_or_else(|| {
            err(
                n,
                format!(
                    "unknown column `{f}`; the header names the columns with their \
                     units: time t_s|t_ms|t_ns, angular rate w{{x,y,z}}_rad_s or \
                     _deg_s (or one table rate rate_deg_s|rate_rad_s), specific \
                     force f{{x,y,z}}_m_s2 or _g, e.g. `{EXAMPLE}`{}",
                    did_you_mean(&name, &COLUMNS)
                ),
            )
        })?;
        let same = |o: &Column| match (o, &c) {
            (Column::Time(_), Column::Time(_)) | (Column::TableRate(_), Column::TableRate(_)) => {
                true
            }
            (Column::Rate(a, _), Column::Rate(b, _))
            | (Column::Force(a, _), Column::Force(b, _)) => a == b,
            _ => false,
        };
        if cols.iter().any(same) {
            return Err(err(n, format!("column `{f}` is given twice")));
        }
        cols.push(c);
    }
    let has = |p: &dyn Fn(&Column) -> bool| cols.iter().filter(|c| p(c)).count();
    let (rates, table_rate) = (
        has(&|c| matches!(c, Column::Rate(..))),
        has(&|c| matches!(c, Column::TableRate(_))),
    );
    if has(&|c| matches!(c, Column::Time(_))) != 1
        || !matches!((rates, table_rate), (3, 0) | (0, 1))
    {
        return Err(err(
            n,
            format!(
                "the header needs a time column and either all three angular rate \
                 columns, e.g. `{EXAMPLE}`, or one table rate column \
                 (`{TABLE_EXAMPLE}`)"
            ),
        ));
    }
    let with_force = match has(&|c| matches!(c, Column::Force(..))) {
        0 => false,
        3 => true,
        _ => {
            return Err(err(
                n,
                "give all three specific force columns (fx, fy, fz) or none".into(),
            ));
        }
    };
    Ok((cols, with_force))
}

/// One row of the log in SI units.
struct Row {
    /// Time, s.
    t_s: f64,
    /// Angular rate, rad/s.
    w_rad_s: [f64; 3],
    /// Specific force, m/s^2 (zero without force columns).
    f_m_s2: [f64; 3],
}

/// Reads data line `n` under the header `cols`; a table rate is turned into a vector about
/// the current table axis, which is recorded in `settings.axis_rows`.
fn parse_row(
    cols: &[Column],
    fields: &[&str],
    n: usize,
    settings: &mut LogSettings,
    file: &str,
) -> Result<Row, ReferenceLogError> {
    let err = |line: usize, message: String| csv_error(file, line, message);
    if fields.len() != cols.len() {
        return Err(err(
            n,
            format!(
                "{} fields, the header names {} columns",
                fields.len(),
                cols.len()
            ),
        ));
    }
    let (mut t, mut w, mut f) = (0.0, [0.0; 3], [0.0; 3]);
    for (c, text) in cols.iter().zip(fields) {
        let v: f64 = text
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| err(n, format!("`{text}` is not a number")))?;
        match *c {
            Column::Time(k) => t = v * k,
            Column::Rate(a, k) => w[a] = v * k,
            Column::Force(a, k) => f[a] = v * k,
            Column::TableRate(k) => {
                let a = settings.axis.ok_or_else(|| {
                    err(
                        n,
                        format!(
                            "a table rate column is the rate about the table axis: say \
                             which sensor axis that is with a line `# table-axis = +z` \
                             (a sensor axis or a vector [x, y, z]) before the rows, \
                             e.g. `{TABLE_EXAMPLE}`"
                        ),
                    )
                })?;
                w = (a * (v * k)).into();
                settings.axis_rows.push(a.into());
            }
        }
    }
    Ok(Row {
        t_s: t,
        w_rad_s: w,
        f_m_s2: f,
    })
}

impl ReferenceLog {
    /// Reads a reference log CSV.
    pub fn load(path: &Path) -> Result<ReferenceLog, ReferenceLogError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ReferenceLogError::Io {
            file: file.clone(),
            source,
        })?;
        ReferenceLog::from_csv_str(&text, &file)
    }

    /// Parses reference log text; `file` names it in messages.
    pub fn from_csv_str(text: &str, file: &str) -> Result<ReferenceLog, ReferenceLogError> {
        let err = |line: usize, message: String| csv_error(file, line, message);
        let mut columns: Option<Vec<Column>> = None;
        let mut log = ReferenceLog {
            file: file.to_string(),
            t_s: Vec::new(),
            angular_rate_rad_s: Vec::new(),
            specific_force_m_s2: None,
            table: None,
        };
        let mut force = Vec::new();
        let mut settings = LogSettings::default();
        for (i, line) in text.lines().enumerate() {
            let n = i + 1;
            let line = line.trim();
            if let Some(comment) = line.strip_prefix('#') {
                settings.read_comment(comment, n, log.t_s.len(), file)?;
                continue;
            }
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let Some(cols) = &columns else {
                let (cols, with_force) = parse_header(&fields, n, file)?;
                if with_force {
                    log.specific_force_m_s2 = Some(Vec::new());
                }
                columns = Some(cols);
                continue;
            };
            let row = parse_row(cols, &fields, n, &mut settings, file)?;
            let t = row.t_s;
            if let Some(&last) = log.t_s.last()
                && t <= last
            {
                return Err(err(
                    n,
                    format!("time {t} s does not increase (previous {last} s)"),
                ));
            }
            log.t_s.push(t);
            log.angular_rate_rad_s.push(row.w_rad_s);
            force.push(row.f_m_s2);
        }
        if columns.is_none() || log.t_s.len() < 2 {
            return Err(err(
                text.lines().count().max(1),
                format!("a reference log needs a header (`{EXAMPLE}`) and at least two rows"),
            ));
        }
        if let Some(f) = &mut log.specific_force_m_s2 {
            *f = force;
        }
        log.table = settings.into_table(file)?;
        Ok(log)
    }
}
