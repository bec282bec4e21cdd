//! Shared by the DDS test and the DDS benchmark: `imud --sim --ros2` and the Cyclone DDS peer
//! (`tests/python/dds_imu_peer.py`) run together inside a network namespace created for the run
//! (`unshare -rn`: new user and network namespaces; only `lo` exists, it is brought up with
//! multicast on and a multicast route), so no DDS packet can reach a real interface.

#![allow(dead_code)] // the test and the bench use different parts

use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use imu_bus::recording::{Recording, read_recording};
use serde_json::Value;

/// How a run ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum End {
    /// When the peer has had no sample for its idle time (the scenario is over).
    PeerIdle,
    /// After this many seconds of imud (for CPU windows); the peer then ends idle.
    AfterS(f64),
}

/// Which readers the peer makes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PeerTopics {
    /// An early reader of every topic, plus a reliable and a late reader of `imu/data`.
    Every,
    /// Early readers of these topics only, by the peer's keys (`imu`, `imu_raw`, `mag`,
    /// `temperature`, `diagnostics`; `imu` must be one), and the late reader.
    Only(&'static [&'static str]),
}

/// One confined run.
#[derive(Debug, Clone)]
pub struct Options {
    /// The simulator's scenario (its `truth = "truth.toml"` is `model`).
    pub scenario: String,
    /// The truth model, also imud's calibration.
    pub model: String,
    /// Extra lines of imud's config file after `[ros2]` (e.g. `qos = "reliable"`).
    pub ros2_config: String,
    /// Start imud with `--ros2`.
    pub ros2: bool,
    /// Run the peer.
    pub peer: bool,
    /// Which readers the peer makes.
    pub topics: PeerTopics,
    /// The peer's late reader starts this long after its first sample.
    pub late_after_s: f64,
    /// How the run ends.
    pub end: End,
    /// Serial line rate of the simulated device (must carry the scenario's rate).
    pub baud: u32,
}

/// A run in progress.
pub struct Started {
    child: Child,
    dir: tempfile::TempDir,
}

/// What a finished run left.
pub struct Run {
    /// The peer's JSON (`Value::Null` without a peer).
    pub peer: Value,
    /// imud's recording.
    pub rec: Recording,
    /// imud's stderr.
    pub imud_log: String,
}

/// True when confinement works here; otherwise says why.
pub fn confinement_available() -> Result<(), String> {
    match Command::new("unshare")
        .args(["-rn", "ip", "link", "set", "lo", "up"])
        .status()
    {
        Ok(s) if s.success() => Ok(()),
        other => Err(format!(
            "no network namespace (unshare -rn ip ...: {other:?})"
        )),
    }
}

/// The shell run inside the namespace; exits with the peer's code, else imud's.
fn script(d: &Path, o: &Options) -> String {
    let peer = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/python/dds_imu_peer.py");
    let d = d.display();
    let start_peer = if o.peer {
        format!(
            r#"python3 {peer} --ready {d}/ready --idle-s 2 --timeout-s 120 --late-after-s {late}{only} > {d}/peer.json 2> {d}/peer.stderr &
P=$!
i=0
while [ ! -f {d}/ready ]; do
  kill -0 $P 2>/dev/null || {{ wait $P; exit $?; }}
  i=$((i+1)); [ $i -lt 600 ] || exit 71
  sleep 0.05
done
"#,
            peer = peer.display(),
            late = o.late_after_s,
            only = match o.topics {
                PeerTopics::Every => String::new(),
                PeerTopics::Only(keys) => format!(" --topics {}", keys.join(",")),
            },
        )
    } else {
        String::new()
    };
    let wait_end = match (o.end, o.peer) {
        (End::PeerIdle, true) => "wait $P; rc=$?\nkill -TERM $I; wait $I; irc=$?\n".to_string(),
        (End::PeerIdle, false) => "wait $I; irc=$?; rc=0\n".to_string(),
        (End::AfterS(s), peer) => format!(
            "sleep {s}\nkill -TERM $I; wait $I; irc=$?\n{}",
            if peer { "wait $P; rc=$?\n" } else { "rc=0\n" }
        ),
    };
    format!(
        r#"ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo || exit 70
{start_peer}IMUD_LOG=info,rustdds=error {imud} --config {d}/imud.toml --name ros2-{pid} --sim {d}/scenario.toml --seed 3 {ros2} 2> {d}/imud.stderr &
I=$!
echo $I > {d}/imud.pid
{wait_end}[ $rc -eq 0 ] || exit $rc
exit $irc
"#,
        imud = env!("CARGO_BIN_EXE_imud"),
        pid = std::process::id(),
        ros2 = if o.ros2 { "--ros2" } else { "" },
    )
}

impl Started {
    /// Writes the files and starts the namespace with daemon and peer.
    pub fn start(o: &Options) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("truth.toml"), &o.model).unwrap();
        std::fs::write(d.join("scenario.toml"), &o.scenario).unwrap();
        std::fs::write(
            d.join("imud.toml"),
            format!(
                "[device]\nbaud = {baud}\n[calibration]\npath = \"{cal}\"\n[log]\ndir = \"{logs}\"\n\
                 [publish]\nenabled = false\n[ros2]\n{extra}\n",
                baud = o.baud,
                cal = d.join("truth.toml").display(),
                logs = d.join("logs").display(),
                extra = o.ros2_config,
            ),
        )
        .unwrap();
        let child = Command::new("unshare")
            .args(["-rn", "sh", "-c", &script(d, o)])
            .spawn()
            .unwrap();
        Self { child, dir }
    }

    /// imud's process id (the namespace shares the PID namespace), once it has started.
    pub fn imud_pid(&self, timeout: Duration) -> Option<u32> {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if let Some(pid) = std::fs::read_to_string(self.dir.path().join("imud.pid"))
                .ok()
                .and_then(|s| s.trim().parse().ok())
            {
                return Some(pid);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }

    fn read(&self, file: &str) -> String {
        std::fs::read_to_string(self.dir.path().join(file)).unwrap_or_default()
    }

    /// Waits for the end; `Err` with the reason when the peer is missing (exit 77).
    pub fn finish(mut self) -> Result<Run, String> {
        let status = self.child.wait().unwrap();
        let imud_log = self.read("imud.stderr");
        if status.code() == Some(77) {
            return Err(format!("the peer is missing: {}", self.read("peer.stderr")));
        }
        assert!(
            status.success(),
            "{status}\npeer: {}\nimud: {imud_log}",
            self.read("peer.stderr")
        );
        let peer_text = self.read("peer.json");
        let peer = if peer_text.is_empty() {
            Value::Null
        } else {
            serde_json::from_str(&peer_text).expect("peer JSON")
        };
        let files: Vec<PathBuf> = std::fs::read_dir(self.dir.path().join("logs"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                let n = p.file_name().unwrap().to_string_lossy().into_owned();
                n.ends_with(".mcap") && !n.contains("truth")
            })
            .collect();
        assert_eq!(files.len(), 1, "{files:?}");
        let rec = read_recording(&files[0]).unwrap();
        assert!(rec.stopped_early.is_none(), "SIGTERM must finish the file");
        Ok(Run {
            peer,
            rec,
            imud_log,
        })
    }
}

/// A run's peer sample stamp, ns since the epoch.
pub fn stamp_ns(s: &Value) -> u64 {
    s["sec"].as_u64().unwrap() * 1_000_000_000 + s["nanosec"].as_u64().unwrap()
}

/// The samples a peer reader received.
pub fn samples<'a>(v: &'a Value, what: &str) -> &'a [Value] {
    v["samples"]
        .as_array()
        .unwrap_or_else(|| panic!("{what}: no samples in {v}"))
}
