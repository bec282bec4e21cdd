//! Physical constants and unit conversion factors used across imud (SI + gauss internally).
//!
//! Conversion factors are named `FROM_TO_TO`: multiply a value in the first unit to get the second,
//! e.g. `rate_rad_s = rate_deg_s * DEG_TO_RAD`.

/// Standard gravity g0 (CGPM 1901), m/s^2. Used to express accelerations in "g".
pub const STANDARD_GRAVITY_M_S2: f64 = 9.80665;
/// Earth's sidereal rotation rate (WGS-84), rad/s; 15.041 deg/h.
pub const EARTH_RATE_RAD_S: f64 = 7.292115e-5;
/// The temperature assumed where none is measured, and the default reference temperature `t0`
/// of the temperature effects, deg C.
pub const REFERENCE_TEMP_C: f64 = 25.0;
/// Degrees to radians.
pub const DEG_TO_RAD: f64 = std::f64::consts::PI / 180.0;
/// Radians to degrees.
pub const RAD_TO_DEG: f64 = 180.0 / std::f64::consts::PI;
/// Seconds in one hour.
pub const SECONDS_PER_HOUR: f64 = 3600.0;
/// deg/h to rad/s (bias stability figures of gyros are usually quoted in deg/h).
pub const DEG_PER_HOUR_TO_RAD_S: f64 = DEG_TO_RAD / SECONDS_PER_HOUR;
/// Angle random walk deg/sqrt(h) to rad/s/sqrt(Hz) (= rad/sqrt(s)): divide by sqrt(3600 s/h) = 60.
pub const DEG_PER_SQRT_HOUR_TO_RAD_PER_SQRT_S: f64 = DEG_TO_RAD / 60.0;
/// Milli-g to m/s^2.
pub const MILLI_G_TO_M_S2: f64 = 1e-3 * STANDARD_GRAVITY_M_S2;
/// Micro-g to m/s^2.
pub const MICRO_G_TO_M_S2: f64 = 1e-6 * STANDARD_GRAVITY_M_S2;
/// Gauss per tesla (1 T = 10^4 G); magnetometer values inside imud are in gauss.
pub const GAUSS_PER_TESLA: f64 = 1e4;
/// Gauss per microtesla (1 uT = 0.01 G).
pub const GAUSS_PER_MICROTESLA: f64 = 1e-2;
/// Offset between degrees Celsius and kelvin; temperature differences are equal in both.
pub const ZERO_CELSIUS_K: f64 = 273.15;
