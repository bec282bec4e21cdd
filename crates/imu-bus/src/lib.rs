//! The shared-memory contract between imud processes: the iceoryx2 services ([`shm`]) that carry
//! the fixed-layout sample types of `imu-rec`.
//!
//! - [`shm`]: the services, their options and the checks of who owns and publishes them.
//! - [`readers`]: imud's streams on a Unix socket for processes in its readers' group (the
//!   records' C-layout bytes behind a small header), and the client that checks the server.
//!
//! The file formats (MCAP recording, truth files, repair, CDR, rosbag2, ROS 1 bags) live in
//! `imu-rec`, which has no shared-memory code, so the offline tools link none; this crate
//! re-exports them so the daemon and the shared-memory clients keep one dependency.

pub mod readers;
pub mod shm;

pub use imu_rec::{
    CalibrationHealth, CorrectedSample, DaemonStatus, McapReadError, RawSample, ReadReport,
    Unfinished, mcap_read, recording, recover, ros1, ros2, sample, truth,
};
