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
        let err = |line: usize, message: String| ReferenceLogError::Csv {
            file: file.to_string(),
            line,
            message,
        };
        const EXAMPLE: &str = "t_s,wx_deg_s,wy_deg_s,wz_deg_s[,fx_m_s2,fy_m_s2,fz_m_s2]";
        const TABLE_EXAMPLE: &str = "# table-axis = +z, then t_s,rate_deg_s";
        let mut columns: Option<Vec<Column>> = None;
        let mut log = ReferenceLog {
            file: file.to_string(),
            t_s: Vec::new(),
            angular_rate_rad_s: Vec::new(),
            specific_force_m_s2: None,
            table: None,
        };
        let mut force = Vec::new();
        // Settings from comment lines: (line, value) of each.
        let mut axis: Option<Vec3> = None;
        let mut axis_rows: Vec<[f64; 3]> = Vec::new();
        let mut axis_lines: Vec<(usize, usize, [f64; 3])> = Vec::new();
        let mut gravity: Option<(usize, f64)> = None;
        let mut latitude: Option<(usize, f64)> = None;
        let mut first_setting: Option<usize> = None;
        for (i, line) in text.lines().enumerate() {
            let n = i + 1;
            let line = line.trim();
            if let Some(comment) = line.strip_prefix('#') {
                let Some((key, value)) = comment.split_once('=') else {
                    continue;
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
                    continue;
                }
                first_setting.get_or_insert(n);
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
                        axis = Some(a);
                        axis_lines.push((n, log.t_s.len(), a.into()));
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
                        if let Some((l, _)) = gravity.replace((n, g)) {
                            return Err(err(n, format!("gravity-m-s2 is given twice (line {l})")));
                        }
                    }
                    _ => {
                        let lat = number()?;
                        if !(-90.0..=90.0).contains(&lat) {
                            return Err(err(n, format!("latitude-deg: {lat} is outside -90..90")));
                        }
                        if let Some((l, _)) = latitude.replace((n, lat)) {
                            return Err(err(n, format!("latitude-deg is given twice (line {l})")));
                        }
                    }
                }
                continue;
            }
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let Some(cols) = &columns else {
                let mut cols = Vec::new();
                for f in &fields {
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
                        (Column::Time(_), Column::Time(_))
                        | (Column::TableRate(_), Column::TableRate(_)) => true,
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
                match has(&|c| matches!(c, Column::Force(..))) {
                    0 => {}
                    3 => log.specific_force_m_s2 = Some(Vec::new()),
                    _ => {
                        return Err(err(
                            n,
                            "give all three specific force columns (fx, fy, fz) or none".into(),
                        ));
                    }
                }
                columns = Some(cols);
                continue;
            };
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
            for (c, text) in cols.iter().zip(&fields) {
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
                        let a = axis.ok_or_else(|| {
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
                        axis_rows.push(a.into());
                    }
                }
            }
            if let Some(&last) = log.t_s.last()
                && t <= last
            {
                return Err(err(
                    n,
                    format!("time {t} s does not increase (previous {last} s)"),
                ));
            }
            log.t_s.push(t);
            log.angular_rate_rad_s.push(w);
            force.push(f);
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
        if axis_rows.is_empty()
            && let Some(l) = first_setting
        {
            return Err(err(
                l,
                format!(
                    "the settings {} apply to a rate table's one-column log (rate_deg_s or \
                     rate_rad_s); this log gives the three axes",
                    SETTINGS.join(", ")
                ),
            ));
        }
        if !axis_rows.is_empty() {
            let latitude_deg = latitude.map(|(_, l)| l);
            let (gravity_m_s2, gravity_source) = match (gravity, latitude_deg) {
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
            log.table = Some(TableLog {
                axis_sensor: axis_rows,
                axis_lines,
                gravity_m_s2,
                gravity_source,
                latitude_deg,
            });
        }
        Ok(log)
    }
}
