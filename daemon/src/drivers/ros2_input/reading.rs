//! A `sensor_msgs/msg/Imu` message as a device reading, decoded by imu-bus's CDR code (the one
//! the rosbag2 readers use): its header stamp is the device clock (ns, the publisher's clock),
//! its `linear_acceleration` and `angular_velocity` the device's own SI reading. The message
//! carries no magnetometer (NaN, never a zero field), no counts and no temperature.

use imu_bus::ros2::{Imu, RosMessage};
use imu_model::Measured;
use imu_model::nalgebra::Vector3;
use tracing::warn;

use super::frame;
use crate::pipeline::{DeviceReading, FrameContent, TickKind, TickLength, Timebase};

/// The clock of a ROS 2 input: the header stamp in whole ns, many ticks a sample.
pub const TIMEBASE: Timebase = Timebase {
    tick: TickLength::WholeNs(1),
    kind: TickKind::Fine,
};

/// Turns frames into frame contents, counting the messages that make no sample.
#[derive(Debug, Default)]
pub struct Readings {
    /// Messages that made no sample so far (the first is said in the log).
    unusable: u64,
}

impl Readings {
    /// Messages that made no sample so far.
    pub fn unusable(&self) -> u64 {
        self.unusable
    }

    /// What one frame carried: a reading, or `unusable` for a message that is no
    /// `sensor_msgs/Imu` in little-endian CDR or whose stamp is zero or before 1970.
    pub fn content(&mut self, frame_bytes: &[u8], topic: &str) -> FrameContent {
        match reading_of(frame::message(frame_bytes)) {
            Ok(reading) => FrameContent {
                reading: Some(reading),
                ..FrameContent::default()
            },
            Err(why) => {
                self.unusable += 1;
                if self.unusable == 1 {
                    warn!(
                        "{topic}: a message that is no usable sensor_msgs/msg/Imu ({why}); \
                         such messages are counted (status packets_unusable), not said again"
                    );
                }
                FrameContent {
                    unusable: true,
                    ..FrameContent::default()
                }
            }
        }
    }
}

/// The reading of one CDR message, or why it has none.
pub fn reading_of(cdr: &[u8]) -> Result<DeviceReading, String> {
    let imu = Imu::from_cdr(cdr).map_err(|e| e.to_string())?;
    let stamp = imu.header.stamp;
    if stamp.sec < 0 || stamp.nanosec >= 1_000_000_000 {
        return Err(format!(
            "header.stamp {}.{:09} s is no time since 1970",
            stamp.sec, stamp.nanosec
        ));
    }
    let t_ns = stamp.to_ns();
    if t_ns == 0 {
        // Without stamps there is no device clock: no rate, no loss count, no fit.
        return Err("header.stamp is zero: the publisher does not stamp its messages".into());
    }
    let v = |v: imu_bus::ros2::Vector3| Vector3::new(v.x, v.y, v.z);
    Ok(DeviceReading {
        ticks_unwrapped: t_ns,
        // The low 16 bits, as a counter device's field would be.
        ticks: (t_ns & 0xFFFF) as u16,
        counts: None,
        measured: Measured {
            accel_m_s2: v(imu.linear_acceleration),
            gyro_rad_s: v(imu.angular_velocity),
            mag_gauss: Vector3::repeat(f64::NAN),
        },
        saturated: false,
        command: 0,
        compensated: None,
        gnss: None,
    })
}
