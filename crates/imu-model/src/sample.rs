//! Sample types shared by the simulator, the daemon and the analysis tools: true motion,
//! measurements, corrected measurements, and the operating conditions effects may depend on.

use crate::Vec3;
use serde::{Deserialize, Serialize};

/// What an effect may depend on besides its own input. All are TRUE physical quantities in
/// the sensor frame (the simulator knows them; the daemon estimates them, see
/// [`crate::Calibration::correct`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Conditions {
    /// Sensor temperature, degrees Celsius.
    pub temp_c: f64,
    /// Time since the sensor was powered on, seconds (drives the warm-up transient).
    pub time_since_power_on_s: f64,
    /// True specific force at the IMU reference point, m/s^2 (drives gyro g-sensitivity).
    pub specific_force_m_s2: Vec3,
    /// True angular rate, rad/s (drives the accelerometer lever arm).
    pub angular_rate_rad_s: Vec3,
    /// True angular acceleration, rad/s^2 (drives the accelerometer lever arm).
    pub angular_accel_rad_s2: Vec3,
}

impl Default for Conditions {
    /// 25 degC, just powered on, no motion.
    fn default() -> Self {
        Conditions {
            temp_c: crate::units::REFERENCE_TEMP_C,
            time_since_power_on_s: 0.0,
            specific_force_m_s2: Vec3::zeros(),
            angular_rate_rad_s: Vec3::zeros(),
            angular_accel_rad_s2: Vec3::zeros(),
        }
    }
}

/// The true motion and field at the IMU reference point, sensor frame (simulator truth).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrueMotion {
    /// True specific force (acceleration minus gravity) at the reference point, m/s^2.
    pub specific_force_m_s2: Vec3,
    /// True angular rate, rad/s.
    pub angular_rate_rad_s: Vec3,
    /// True angular acceleration, rad/s^2.
    pub angular_accel_rad_s2: Vec3,
    /// True magnetic flux density, gauss.
    pub mag_field_gauss: Vec3,
}

/// One IMU sample as the sensor reports it, in physical units (after the device's own scaling).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measured {
    /// Measured specific force, m/s^2.
    pub accel_m_s2: Vec3,
    /// Measured angular rate, rad/s.
    pub gyro_rad_s: Vec3,
    /// Measured magnetic flux density, gauss.
    pub mag_gauss: Vec3,
}

/// A measurement with the calibration's deterministic errors removed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Corrected {
    /// Corrected specific force at the IMU reference point, m/s^2.
    pub accel_m_s2: Vec3,
    /// Corrected angular rate, rad/s.
    pub gyro_rad_s: Vec3,
    /// Corrected magnetic flux density, gauss.
    pub mag_gauss: Vec3,
    /// False if the accel/gyro coupling iteration (lever arm <-> g-sensitivity) did not settle
    /// to 1e-13 relative within its iteration budget; the values are then the last iterate.
    pub converged: bool,
}
