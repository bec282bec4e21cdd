//! A simulated unplug on a real pseudo-terminal: the stable link goes away with the device (as
//! udev removes it) and comes back pointing at the new pty. Left pointing at the old pty's
//! number while unplugged, it led a host retrying the path into whichever pty reused that
//! number (another simulator's, in a parallel test), with its commands onto that line.

use std::path::Path;
use std::time::{Duration, Instant};

use imu_sim::{Pacing, SimOptions, spawn};

const SCENARIO: &str = r#"
name = "unplug"
rate-hz = 100.0
[[segment]]
kind = "static"
duration-s = 30.0
"#;

/// Polls `cond` until it holds or `timeout` passes; whether it held.
fn eventually(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    cond()
}

fn present(link: &Path) -> bool {
    std::fs::symlink_metadata(link).is_ok()
}

#[test]
fn the_link_is_gone_while_unplugged_and_comes_back_at_the_new_pty() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("unplug.toml");
    std::fs::write(&scenario, SCENARIO).unwrap();
    let link = dir.path().join("imu0");
    let mut opts = SimOptions::from_files(&scenario, None).unwrap();
    opts.link = Some(link.clone());
    opts.pacing = Pacing::RealTime;
    let sim = spawn(opts).unwrap();
    assert!(eventually(Duration::from_secs(5), || present(&link)));
    let before = std::fs::read_link(&link).unwrap();
    assert!(before.exists(), "{} points at a live pty", before.display());

    sim.unplug(Duration::from_secs(1));
    assert!(
        eventually(Duration::from_secs(2), || !present(&link)),
        "the link still points at {} while the device is unplugged",
        before.display()
    );
    assert!(eventually(Duration::from_secs(5), || present(&link)));
    let after = std::fs::read_link(&link).unwrap();
    assert_ne!(after, before, "a new pty");
    assert!(after.exists());
    sim.stop();
}
