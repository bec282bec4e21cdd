//! The Earth as a reference: WGS-84 normal gravity, the split of Earth's rotation rate into
//! its vertical and horizontal parts at a latitude, and what an unknown heading (or an unknown
//! latitude) leaves unknown of it on a sensor axis. The constants themselves are in
//! [`crate::units`].

use crate::units::EARTH_RATE_RAD_S;

/// WGS-84 normal gravity on the ellipsoid (Somigliana's formula) at a geodetic latitude, with
/// the free-air correction for `height_m` above it, m/s^2: 9.7803 at the equator, 9.8017 at
/// 40 deg, 9.8322 at the poles.
pub fn normal_gravity_m_s2(latitude_deg: f64, height_m: f64) -> f64 {
    /// Normal gravity at the equator, m/s^2.
    const GAMMA_EQUATOR_M_S2: f64 = 9.780_325_335_9;
    /// Somigliana's constant.
    const K: f64 = 0.001_931_852_652_41;
    /// First eccentricity squared (NIMA TR8350.2: 6.694 379 990 14e-3).
    const E2: f64 = 0.006_694_379_990_14;
    /// Free-air gradient, (m/s^2)/m.
    const FREE_AIR_PER_M: f64 = 3.086e-6;
    let s2 = latitude_deg.to_radians().sin().powi(2);
    GAMMA_EQUATOR_M_S2 * (1.0 + K * s2) / (1.0 - E2 * s2).sqrt() - FREE_AIR_PER_M * height_m
}

/// Earth's rate at a latitude split into its vertical (up) and horizontal (north) parts, rad/s.
pub fn earth_rate_split_rad_s(latitude_deg: f64) -> (f64, f64) {
    let l = latitude_deg.to_radians();
    (EARTH_RATE_RAD_S * l.sin(), EARTH_RATE_RAD_S * l.cos())
}

/// Variance, (rad/s)^2, of the part of Earth's rate a reference cannot know on a sensor axis
/// whose component along the up direction is `up_component`: with a latitude, the horizontal
/// part `Omega cos L` points to an unknown heading (uniform over the circle, so each horizontal
/// direction has variance `(Omega cos L)^2 / 2`, and the axis sees `1 - u^2` of it); without
/// one, the whole rate points anywhere (`Omega^2 / 3` per axis).
pub fn unknown_heading_variance_rad2_s2(latitude_deg: Option<f64>, up_component: f64) -> f64 {
    match latitude_deg {
        Some(lat) => {
            let (_, horizontal) = earth_rate_split_rad_s(lat);
            horizontal.powi(2) * (1.0 - up_component * up_component).max(0.0) / 2.0
        }
        None => EARTH_RATE_RAD_S.powi(2) / 3.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_gravity_matches_wgs84_reference_values() {
        // NIMA TR8350.2 Table 4.1 (normal gravity on the ellipsoid).
        assert!((normal_gravity_m_s2(0.0, 0.0) - 9.780_325_336).abs() < 1e-9);
        // The pole value is a separate defining constant: it checks k and e^2.
        assert!((normal_gravity_m_s2(90.0, 0.0) - 9.832_184_937_8).abs() < 1e-9);
        assert!((normal_gravity_m_s2(45.0, 0.0) - 9.806_197_6).abs() < 1e-6);
        assert_eq!(
            normal_gravity_m_s2(-30.0, 0.0),
            normal_gravity_m_s2(30.0, 0.0)
        );
        let dg = normal_gravity_m_s2(40.0, 0.0) - normal_gravity_m_s2(40.0, 1000.0);
        assert!((dg - 3.086e-3).abs() < 1e-12);
    }

    #[test]
    fn earth_rate_split_and_unknown_heading() {
        let (v, h) = earth_rate_split_rad_s(30.0);
        assert!((v - EARTH_RATE_RAD_S * 0.5).abs() < 1e-18);
        assert!((v * v + h * h - EARTH_RATE_RAD_S.powi(2)).abs() < 1e-22);
        // A vertical axis sees none of the horizontal part; a horizontal one half its square.
        assert_eq!(unknown_heading_variance_rad2_s2(Some(30.0), 1.0), 0.0);
        assert!((unknown_heading_variance_rad2_s2(Some(30.0), 0.0) - h * h / 2.0).abs() < 1e-24);
        let all = unknown_heading_variance_rad2_s2(None, 0.3);
        assert!((all - EARTH_RATE_RAD_S.powi(2) / 3.0).abs() < 1e-24);
    }
}
