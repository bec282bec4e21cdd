//! Results equal across storage formats: one of our recordings converted by Python `rosbags`
//! into a rosbag2 MCAP bag, a rosbag2 sqlite3 bag and a ROS 1 bag gives the same
//! `imu-analyze impact REC --json` on each (`tests/ros_formats/mod.rs`).

#[path = "../../../tests/ros_formats/mod.rs"]
mod ros_formats;

use std::ffi::OsStr;

#[test]
fn the_same_results_from_mcap_sqlite3_and_ros1_bags() {
    let dir = tempfile::tempdir().unwrap();
    let recording = ros_formats::record(dir.path());
    let Some(converted) = ros_formats::convert(&recording, dir.path()) else {
        return;
    };
    let plan = ros_formats::repo().join("config/plans/index-table-12pos.toml");
    let model = ros_formats::repo().join("config/models/bias-scale-misalignment.toml");
    let _ = (&plan, &model);
    let args: &[&OsStr] = &["--json".as_ref()];
    ros_formats::assert_same(
        env!("CARGO_BIN_EXE_imu-analyze"),
        &["impact".as_ref()],
        &converted,
        args,
    );
}
