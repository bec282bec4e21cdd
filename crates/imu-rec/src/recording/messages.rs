//! The standard messages built from samples (`sensor_msgs/msg/Imu`, `MagneticField`,
//! `Temperature`) and their headers, shared by the writer, the readers' tests and the daemon's
//! DDS publisher (so a DDS subscriber gets the very messages the MCAP `/imu/data` stores).

use super::*;

/// A header stamped `t_ns` (host wall clock, ns) in `frame_id`.
pub fn header(t_ns: u64, frame_id: &str) -> Header {
    Header {
        stamp: Time::from_ns(t_ns),
        frame_id: frame_id.to_string(),
    }
}

/// The `/imu/data` message of a corrected sample: no orientation estimate (covariance element
/// 0 = -1, identity quaternion), rates and accelerations with diagonal covariances from `noise`
/// (all zeros, "unknown", without).
pub fn imu_message(
    sample: &CorrectedSample,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
) -> Imu {
    let diag = |v: Option<[f64; 3]>| v.map(ros2::diagonal_covariance).unwrap_or([0.0; 9]);
    Imu {
        header: header(sample.t_wall_ns, frame_id),
        orientation: Quaternion::default(),
        orientation_covariance: ros2::NOT_PROVIDED_COVARIANCE,
        angular_velocity: sample.gyro_rad_s.into(),
        angular_velocity_covariance: diag(noise.map(|n| n.gyro_var_rad2_s2)),
        linear_acceleration: sample.accel_m_s2.into(),
        linear_acceleration_covariance: diag(noise.map(|n| n.accel_var_m2_s4)),
    }
}

/// The `/imu/device_compensated` message of a unit's compensated reading at `t_wall_ns`:
/// covariances unknown (zeros), orientation not provided.
pub fn device_compensated_message(t_wall_ns: u64, c: &DeviceCompensated, frame_id: &str) -> Imu {
    Imu {
        header: header(t_wall_ns, frame_id),
        orientation: Quaternion::default(),
        orientation_covariance: ros2::NOT_PROVIDED_COVARIANCE,
        angular_velocity: c.gyro_rad_s.into(),
        angular_velocity_covariance: [0.0; 9],
        linear_acceleration: c.accel_m_s2.into(),
        linear_acceleration_covariance: [0.0; 9],
    }
}

/// The `/imu/mag` message of a corrected sample (gauss converted to tesla).
pub fn magnetic_field_message(
    sample: &CorrectedSample,
    frame_id: &str,
    noise: Option<&ImuNoiseVariances>,
) -> MagneticField {
    MagneticField {
        header: header(sample.t_wall_ns, frame_id),
        magnetic_field: sample.mag_gauss.map(|g| g * TESLA_PER_GAUSS).into(),
        magnetic_field_covariance: noise
            .map(|n| ros2::diagonal_covariance(n.mag_var_t2))
            .unwrap_or([0.0; 9]),
    }
}

/// The `/imu/temperature` message of a temperature reading (variance unknown: 0).
pub fn temperature_message(t_wall_ns: u64, temp_c: f64, frame_id: &str) -> Temperature {
    Temperature {
        header: header(t_wall_ns, frame_id),
        temperature: temp_c,
        variance: 0.0,
    }
}
