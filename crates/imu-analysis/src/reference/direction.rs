//! Sensor directions as written in plans and reference logs: `+z`, `-x`, `y` or `[x, y, z]`.

use imu_model::Vec3;

/// A sensor direction written as in plans, `+z`, `-x`, `y` or `[x, y, z]` (normalised), from
/// text (a reference log's `# table-axis = ...` line).
pub fn parse_direction(s: &str) -> Option<Vec3> {
    let s = s.trim();
    if let Some(inner) = s.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
        let v: Vec<f64> = inner
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()?;
        let [x, y, z] = v.as_slice() else {
            return None;
        };
        let d = Vec3::new(*x, *y, *z);
        return (d.iter().all(|c| c.is_finite()) && d.norm() > 1e-9).then(|| d.normalize());
    }
    parse_axis(s)
}

pub(crate) fn parse_axis(s: &str) -> Option<Vec3> {
    let (sign, name) = match s.as_bytes().first() {
        Some(b'-') => (-1.0, &s[1..]),
        Some(b'+') => (1.0, &s[1..]),
        _ => (1.0, s),
    };
    let v = match name {
        "x" => Vec3::x(),
        "y" => Vec3::y(),
        "z" => Vec3::z(),
        _ => return None,
    };
    Some(v * sign)
}

/// `+z` for an axis-aligned unit vector, else `[0.000, 0.866, 0.500]`.
pub fn format_direction(v: &Vec3) -> String {
    let names = ["x", "y", "z"];
    let i = v.iamax();
    if (v.norm() - 1.0).abs() < 1e-9 && (v[i].abs() - 1.0).abs() < 1e-9 {
        format!("{}{}", if v[i] < 0.0 { "-" } else { "+" }, names[i])
    } else {
        format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
    }
}
