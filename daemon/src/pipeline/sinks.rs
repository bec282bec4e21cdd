//! Where the per-frame path's output goes, and the calibration it applies.
//! (The readers' socket server is its own file, `readers.rs`.)

use imu_bus::recording::{ImuNoiseVariances, LogRecord, Recorder};
use imu_bus::shm::Publishers;
use imu_model::{Calibration, SealedCalibration};

/// The calibration in force, ready for the per-sample path.
#[derive(Debug, Clone)]
pub struct ActiveCalibration {
    /// The model, sealed: its inverse prepared once at load, no per-sample check that it is
    /// still the model it was prepared from (nothing can change it; a reload is a new one).
    pub model: SealedCalibration,
    /// Its content id as a number (published with every corrected sample).
    pub id: u64,
}

impl ActiveCalibration {
    /// Wraps a loaded calibration.
    pub fn new(model: Calibration) -> Self {
        let id = u64::from_str_radix(&model.content_id(), 16).unwrap_or(0);
        Self {
            model: SealedCalibration::new(model),
            id,
        }
    }
}

/// Where the pipeline's output goes.
#[derive(Default)]
pub struct Sinks {
    /// Shared-memory publishers.
    pub publishers: Option<Publishers>,
    /// The readers' socket (the same streams for the readers' group).
    pub readers: Option<super::readers::ReadersServer>,
    /// The MCAP recorder.
    pub recorder: Option<Recorder>,
    /// The ROS 2 topics over DDS (gets what is logged, through its own bounded queue).
    pub ros2: Option<crate::ros2::Ros2Sink>,
}

impl Sinks {
    /// Logs a calibration put in force; `sample_rate_hz` turns its white-noise densities into
    /// per-sample variances for the ROS covariance fields (unknown rate: covariance unknown).
    pub fn log_calibration(
        &self,
        t_wall_ns: u64,
        cal: &ActiveCalibration,
        sample_rate_hz: Option<f64>,
    ) {
        let variances = |t: &imu_model::TriadModel, unit_scale: f64| {
            t.noise.as_ref().map(|n| {
                let fs = sample_rate_hz.unwrap_or(f64::NAN);
                n.white_density.map(|d| (d * unit_scale).powi(2) * fs)
            })
        };
        let noise = match (
            sample_rate_hz,
            variances(&cal.model.accel, 1.0),
            variances(&cal.model.gyro, 1.0),
        ) {
            (Some(_), Some(accel_var_m2_s4), Some(gyro_var_rad2_s2)) => Some(ImuNoiseVariances {
                accel_var_m2_s4,
                gyro_var_rad2_s2,
                // gauss -> tesla for sensor_msgs/MagneticField.
                mag_var_t2: variances(&cal.model.mag, 1e-4).unwrap_or([0.0; 3]),
            }),
            _ => None,
        };
        self.log(LogRecord::Calibration {
            t_wall_ns,
            id: format!("{:016x}", cal.id),
            toml: cal.model.to_toml_string(),
            noise,
        });
    }

    /// True if anything logs records (the recorder, ROS 2).
    pub(crate) fn logs(&self) -> bool {
        self.recorder.is_some() || self.ros2.is_some()
    }

    pub(crate) fn log(&self, record: LogRecord) {
        if let Some(d) = &self.ros2 {
            d.offer(&record);
        }
        if let Some(r) = &self.recorder {
            // A full queue drops the record; the recorder counts it.
            let _ = r.log(record);
        }
    }
}
