//! Who may publish on imud's services, with real users (the test creates them, so it runs as
//! root; CI does, and `IMUD_REQUIRE_PEERS` makes a non-root run fail instead of skip).
//!
//! iceoryx2 0.10 creates every resource for its owner only (0600 segments, 0750 directories); it
//! offers no group mode (only the build-time `dev_permissions`, which makes everything world
//! read-write). So another user can neither read nor write the services of an imud running as
//! `imud`. What iceoryx2 does not stop is a process of another user creating the services
//! first (with its own permissions, e.g. world read-write): that is what the checks here are
//! for. The test runs an impostor `imud --sim` as one user and the real one as another:
//!
//! - the real imud refuses the impostor's services, naming the user who created them;
//! - the impostor's own user receives its samples (the services work), the real daemon's user
//!   cannot open them, and root, which may open anything, refuses them: they were not created
//!   by a user it trusts;
//! - once the real imud runs, the impostor is refused the same way, and a subscriber of another
//!   user cannot open the services at all.
//!
//! Since iceoryx2 cannot serve other users, imud serves them on its readers' socket (mode 0660,
//! group `[publish] group`); the second test runs imud as a user in a readers' group and checks
//! that a member gets every sample (the same records as shared memory), a non-member is refused
//! by the kernel, and another user can neither take the socket's path nor pass a socket of its
//! own off as imud's (the client's `SO_PEERCRED` check).

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The two users the test creates: the real daemon's and an impostor's.
const REAL: &str = "imudt-real";
const IMPOSTOR: &str = "imudt-impostor";

/// A workspace binary beside this test's executable (`cargo test --workspace` builds them).
fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().unwrap().parent().unwrap();
    let path = dir.join(name);
    assert!(
        path.exists(),
        "{} is missing: build it first (cargo build -p imud -p imu-echo)",
        path.display()
    );
    path
}

/// Whether the test can create users; otherwise it skips, or fails under CI.
fn root_or_skip() -> bool {
    let root = nix_uid() == 0;
    if !root {
        assert!(
            std::env::var_os("IMUD_REQUIRE_PEERS").is_none(),
            "the access test creates users and must run as root under IMUD_REQUIRE_PEERS"
        );
        eprintln!("skipping the access test: not root");
    }
    root
}

fn nix_uid() -> u32 {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self").unwrap().uid()
}

/// Creates the system user `name` unless it exists.
fn ensure_user(name: &str) {
    let exists = Command::new("id")
        .arg(name)
        .output()
        .unwrap()
        .status
        .success();
    if !exists {
        let out = Command::new("useradd")
            .args([
                "--system",
                "--no-create-home",
                "--shell",
                "/usr/sbin/nologin",
                name,
            ])
            .output()
            .unwrap();
        assert!(out.status.success(), "useradd {name}: {out:?}");
    }
}

/// A command run as `user` (its uid, primary gid, no supplementary groups) in `dir`, whose
/// `config/iceoryx2.toml` points iceoryx2 at a root directory of the test's own.
fn as_user(user: &str, dir: &Path, program: &Path) -> Command {
    let mut cmd = Command::new("setpriv");
    cmd.args(["--reuid", user, "--regid", user, "--clear-groups", "--"])
        .arg(program)
        .current_dir(dir)
        .env_remove("IMUD_CONFIG")
        .env("IMUD_LOG", "info");
    cmd
}

/// A directory every test user may use: the processes' working directory with iceoryx2's
/// project-local config, their iceoryx2 root and their logs.
fn shared_dir(parent: &Path, name: &str) -> PathBuf {
    let dir = parent.join(name);
    for sub in ["config", "iox", "logs"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        std::fs::set_permissions(dir.join(sub), std::fs::Permissions::from_mode(0o1777)).unwrap();
    }
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::write(
        dir.join("config/iceoryx2.toml"),
        format!("[global]\nroot-path = \"{}/\"\n", dir.join("iox").display()),
    )
    .unwrap();
    dir
}

struct Daemon {
    child: Child,
    log: PathBuf,
}

impl Daemon {
    fn start(user: &str, dir: &Path, instance: &str, tag: &str) -> Daemon {
        let log = dir.join(format!("imud-{tag}.stderr"));
        let child = as_user(user, dir, &bin("imud"))
            .args(["--sim", "--name", instance, "--log-dir"])
            .arg(dir.join("logs"))
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap();
        Daemon { child, log }
    }

    fn stderr(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Waits (polling, up to `limit`) until the daemon exits; its status, or None if it runs on.
    fn wait_exit(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let deadline = Instant::now() + limit;
        while Instant::now() < deadline {
            if let Some(status) = self.child.try_wait().unwrap() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        None
    }

    fn stop(mut self) {
        let pid = self.child.id().to_string();
        Command::new("kill").args(["-TERM", &pid]).status().unwrap();
        let status = self.wait_exit(Duration::from_secs(20));
        assert!(
            status.is_some_and(|s| s.success()),
            "imud did not stop cleanly ({status:?}): {}",
            self.stderr()
        );
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `imu-echo` as `user`: `count` corrected samples as JSON lines, trusting `trust` if given
/// (by default: root, its own user and `imud`).
fn echo(user: &str, dir: &Path, instance: &str, trust: Option<&str>, count: u32) -> Output {
    let mut cmd = as_user(user, dir, &bin("imu-echo"));
    cmd.args([
        "--name",
        instance,
        "--format",
        "jsonl",
        "--quiet",
        "--timeout-s",
        "20",
    ])
    .args(["--count", &count.to_string()]);
    if let Some(t) = trust {
        cmd.args(["--publisher-user", t]);
    }
    cmd.output().unwrap()
}

fn text(out: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// The `seq` of every JSON line.
fn seqs(out: &Output) -> Vec<u64> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["seq"].as_u64().unwrap()
        })
        .collect()
}

#[test]
fn only_the_user_who_created_the_services_publishes_and_subscribers_check_who_that_is() {
    if !root_or_skip() {
        return;
    }
    ensure_user(REAL);
    ensure_user(IMPOSTOR);
    let tmp = tempfile::tempdir().unwrap();
    std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let instance = format!("access-{}", std::process::id());

    // Phase 1: the impostor creates the services first.
    let dir = shared_dir(tmp.path(), "impostor-first");
    let impostor = Daemon::start(IMPOSTOR, &dir, &instance, "impostor");
    // Its own user's subscriber trusts it (its own user) and receives consecutive samples: the
    // services exist and work.
    let own = echo(IMPOSTOR, &dir, &instance, None, 20);
    assert!(own.status.success(), "{}", text(&own));
    let s = seqs(&own);
    assert_eq!(s.len(), 20, "{}", text(&own));
    assert!(s.windows(2).all(|w| w[1] == w[0] + 1), "{s:?}");

    // The real daemon's user cannot even open them (iceoryx2's owner-only resources).
    let blocked = echo(REAL, &dir, &instance, None, 1);
    assert!(!blocked.status.success(), "{}", text(&blocked));
    assert!(blocked.stdout.is_empty(), "{}", text(&blocked));

    // Root may open anything; its subscriber refuses the impostor's services by default (root,
    // itself, `imud`) and when told to trust the real daemon's user.
    for trust in [None, Some(REAL)] {
        let refused = echo("root", &dir, &instance, trust, 5);
        let t = text(&refused);
        assert_eq!(refused.status.code(), Some(1), "{t}");
        assert!(refused.stdout.is_empty(), "no sample may be printed: {t}");
        assert!(t.contains("not a trusted imud publisher"), "{t}");
        assert!(t.contains(&format!("user {IMPOSTOR}")), "{t}");
    }

    // The real daemon refuses to share the impostor's services and names who created them.
    let mut real = Daemon::start(REAL, &dir, &instance, "real-refused");
    let status = real.wait_exit(Duration::from_secs(30));
    let log = real.stderr();
    assert!(status.is_some_and(|s| !s.success()), "{status:?}: {log}");
    assert!(log.contains("was created by user imudt-impostor"), "{log}");
    assert!(log.contains("imud does not share services"), "{log}");
    drop(real);
    impostor.stop();

    // Phase 2: the real daemon first; its own user's subscriber receives.
    let dir = shared_dir(tmp.path(), "real-first");
    let real = Daemon::start(REAL, &dir, &instance, "real");
    let got = echo(REAL, &dir, &instance, None, 20);
    assert!(got.status.success(), "{}", text(&got));
    assert_eq!(seqs(&got).len(), 20, "{}", text(&got));

    // Another user cannot open the services (iceoryx2's owner-only resources).
    let other = echo(IMPOSTOR, &dir, &instance, Some(REAL), 1);
    assert!(!other.status.success(), "{}", text(&other));
    assert!(other.stdout.is_empty(), "{}", text(&other));

    // The impostor cannot take them over: its imud refuses, naming the real user.
    let mut late = Daemon::start(IMPOSTOR, &dir, &instance, "impostor-refused");
    let status = late.wait_exit(Duration::from_secs(30));
    let log = late.stderr();
    assert!(status.is_some_and(|s| !s.success()), "{status:?}: {log}");
    assert!(log.contains("was created by user imudt-real"), "{log}");
    drop(late);

    // And the real daemon went on publishing to its subscribers throughout.
    let after = echo(REAL, &dir, &instance, Some(REAL), 5);
    assert!(after.status.success(), "{}", text(&after));
    real.stop();
}

/// The users and the group of the readers' socket test (names apart from the test above, which
/// runs in parallel and creates its own).
const GROUP: &str = "imudt-readers";
const DAEMON: &str = "imudt-grp-daemon";
const MEMBER: &str = "imudt-grp-member";
const OUTSIDER: &str = "imudt-grp-outsider";

/// Creates the system group `name` unless it exists.
fn ensure_group(name: &str) {
    let exists = Command::new("getent")
        .args(["group", name])
        .output()
        .unwrap()
        .status
        .success();
    if !exists {
        let out = Command::new("groupadd")
            .args(["--system", name])
            .output()
            .unwrap();
        assert!(out.status.success(), "groupadd {name}: {out:?}");
    }
}

/// Adds `user` to `group` (a no-op when it is a member already).
fn add_to_group(user: &str, group: &str) {
    let out = Command::new("usermod")
        .args(["--append", "--groups", group, user])
        .output()
        .unwrap();
    assert!(out.status.success(), "usermod {user}: {out:?}");
}

/// As [`as_user`], with the user's supplementary groups from /etc/group (as a login has them).
fn as_member(user: &str, dir: &Path, program: &Path) -> Command {
    let mut cmd = Command::new("setpriv");
    cmd.args(["--reuid", user, "--regid", user, "--init-groups", "--"])
        .arg(program)
        .current_dir(dir)
        .env_remove("IMUD_CONFIG")
        .env("IMUD_LOG", "info");
    cmd
}

/// `imud --sim` as `user` with `config`, its stderr in `dir`.
fn start_with_config(user: &str, dir: &Path, config: &Path, instance: &str, tag: &str) -> Daemon {
    let log = dir.join(format!("imud-{tag}.stderr"));
    let child = as_member(user, dir, &bin("imud"))
        .arg("--config")
        .arg(config)
        .args(["--sim", "--name", instance, "--log-dir"])
        .arg(dir.join("logs"))
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    Daemon { child, log }
}

/// A directory owned by `user`, mode 0755: what systemd's RuntimeDirectory= gives imud.
fn runtime_dir(parent: &Path, name: &str, user: &str) -> PathBuf {
    let dir = parent.join(name);
    std::fs::create_dir_all(&dir).unwrap();
    let out = Command::new("chown")
        .args([&format!("{user}:{user}"), dir.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).unwrap();
    dir
}

/// `imu-echo --socket` as `user` (with its groups): `count` records of `stream` as JSON lines.
fn echo_socket(
    user: &str,
    dir: &Path,
    socket: &Path,
    stream: &str,
    trust: Option<&str>,
    count: u32,
) -> Command {
    let mut cmd = as_member(user, dir, &bin("imu-echo"));
    cmd.arg("--socket")
        .arg(socket)
        .args([stream, "--format", "jsonl", "--timeout-s", "20"])
        .args(["--count", &count.to_string()]);
    if let Some(t) = trust {
        cmd.args(["--publisher-user", t]);
    }
    cmd
}

/// The JSON lines of an output, by `seq`.
fn by_seq(out: &Output) -> std::collections::BTreeMap<u64, String> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            (v["seq"].as_u64().unwrap(), l.to_owned())
        })
        .collect()
}

#[test]
fn members_of_the_readers_group_get_every_sample_on_the_socket_and_no_one_else_serves_it() {
    if !root_or_skip() {
        return;
    }
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    ensure_group(GROUP);
    for user in [DAEMON, MEMBER, OUTSIDER] {
        ensure_user(user);
    }
    add_to_group(DAEMON, GROUP);
    add_to_group(MEMBER, GROUP);
    let tmp = tempfile::tempdir().unwrap();
    std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    let instance = format!("readers-{}", std::process::id());

    let dir = shared_dir(tmp.path(), "group");
    let run = runtime_dir(&dir, "run", DAEMON);
    let socket = run.join("readers.sock");
    let config = dir.join("imud.toml");
    std::fs::write(
        &config,
        format!(
            "[publish]\nreaders-socket = \"{}\"\ngroup = \"{GROUP}\"\n",
            socket.display()
        ),
    )
    .unwrap();
    let daemon = start_with_config(DAEMON, &dir, &config, &instance, "daemon");

    // A member (trusting the daemon's user, as it would trust `imud`) receives consecutive
    // samples on the socket while the daemon's own user reads the same stream from shared
    // memory: the records agree to the byte (same JSON).
    let member =
        echo_socket(MEMBER, &dir, &socket, "--corrected", Some(DAEMON), 300).output_async();
    let own = as_member(DAEMON, &dir, &bin("imu-echo"))
        .args([
            "--name",
            &instance,
            "--format",
            "jsonl",
            "--quiet",
            "--timeout-s",
            "20",
        ])
        .args(["--count", "300"])
        .output()
        .unwrap();
    let member = member.wait_with_output().unwrap();
    assert!(member.status.success(), "{}", text(&member));
    assert!(own.status.success(), "{}", text(&own));
    let got = by_seq(&member);
    let seqs: Vec<u64> = got.keys().copied().collect();
    assert_eq!(seqs.len(), 300, "{}", text(&member));
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "gaps: {seqs:?}");
    let t = text(&member);
    assert!(
        t.contains(", 0 missed (seq gaps), 0 packets the daemon could not queue"),
        "{t}"
    );
    let shm = by_seq(&own);
    let common: Vec<u64> = shm
        .keys()
        .filter(|s| got.contains_key(s))
        .copied()
        .collect();
    assert!(
        common.len() >= 50,
        "the two readers overlap by {} samples",
        common.len()
    );
    for s in common {
        assert_eq!(got[&s], shm[&s], "seq {s}");
    }

    // The daemon's status on the socket counts at least every sample the member saw, and no
    // publishing drop.
    let status = echo_socket(MEMBER, &dir, &socket, "--status", Some(DAEMON), 1)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", text(&status));
    let st: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&status.stdout).trim()).unwrap();
    assert!(
        st["samples"].as_u64().unwrap() >= *seqs.last().unwrap(),
        "{st}"
    );
    assert_eq!(st["publish_drops"].as_u64(), Some(0), "{st}");

    // The socket is the daemon's, 0660, in the readers' group.
    let m = std::fs::symlink_metadata(&socket).unwrap();
    assert!(m.file_type().is_socket());
    assert_eq!(m.mode() & 0o777, 0o660);
    let gid = |name: &str| {
        let out = Command::new("getent")
            .args(["group", name])
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout)
            .split(':')
            .nth(2)
            .unwrap()
            .parse::<u32>()
            .unwrap()
    };
    assert_eq!(m.gid(), gid(GROUP));
    let ino = m.ino();

    // A non-member is refused by the kernel, with a message that says why.
    let refused = echo_socket(OUTSIDER, &dir, &socket, "--corrected", Some(DAEMON), 1)
        .output()
        .unwrap();
    let t = text(&refused);
    assert_eq!(refused.status.code(), Some(1), "{t}");
    assert!(refused.stdout.is_empty(), "{t}");
    assert!(t.contains("permission denied connecting to"), "{t}");
    assert!(t.contains(&format!("group {GROUP}")), "{t}");

    // The outsider can neither remove nor replace the socket: the directory is the daemon's.
    let rm = as_member(OUTSIDER, &dir, Path::new("/bin/rm"))
        .arg("-f")
        .arg(&socket)
        .output()
        .unwrap();
    assert!(!rm.status.success(), "{}", text(&rm));
    // Nor can its own imud take the path: it refuses a directory another user owns.
    let odir = shared_dir(tmp.path(), "outsider");
    let oconfig = odir.join("imud.toml");
    std::fs::write(
        &oconfig,
        format!("[publish]\nreaders-socket = \"{}\"\n", socket.display()),
    )
    .unwrap();
    let oinstance = format!("{instance}-o");
    let mut taker = start_with_config(OUTSIDER, &odir, &oconfig, &oinstance, "taker");
    let status = taker.wait_exit(Duration::from_secs(30));
    let log = taker.stderr();
    assert!(status.is_some_and(|s| !s.success()), "{status:?}: {log}");
    assert!(log.contains("is not safe: it belongs to uid"), "{log}");
    drop(taker);
    assert_eq!(std::fs::symlink_metadata(&socket).unwrap().ino(), ino);

    // The outsider's imud on a socket of its own, opened to everyone: a member's imu-echo
    // refuses it (SO_PEERCRED names the outsider), by default and trusting the daemon's user.
    let orun = runtime_dir(&odir, "run", OUTSIDER);
    let osocket = orun.join("readers.sock");
    std::fs::write(
        &oconfig,
        format!("[publish]\nreaders-socket = \"{}\"\n", osocket.display()),
    )
    .unwrap();
    let outsider = start_with_config(OUTSIDER, &odir, &oconfig, &oinstance, "outsider");
    let deadline = Instant::now() + Duration::from_secs(30);
    while !osocket.exists() {
        assert!(Instant::now() < deadline, "{}", outsider.stderr());
        std::thread::sleep(Duration::from_millis(50));
    }
    let chmod = as_member(OUTSIDER, &odir, Path::new("/bin/chmod"))
        .arg("666")
        .arg(&osocket)
        .output()
        .unwrap();
    assert!(chmod.status.success(), "{}", text(&chmod));
    for trust in [None, Some(DAEMON)] {
        let fake = echo_socket(MEMBER, &dir, &osocket, "--corrected", trust, 5)
            .output()
            .unwrap();
        let t = text(&fake);
        assert_eq!(fake.status.code(), Some(1), "{t}");
        assert!(fake.stdout.is_empty(), "no sample may be printed: {t}");
        assert!(t.contains("not a trusted imud publisher"), "{t}");
        assert!(t.contains(&format!("user {OUTSIDER}")), "{t}");
    }
    outsider.stop();

    // The real daemon served its members throughout; it removes its socket when it stops.
    let after = echo_socket(MEMBER, &dir, &socket, "--corrected", Some(DAEMON), 5)
        .output()
        .unwrap();
    assert!(after.status.success(), "{}", text(&after));
    daemon.stop();
    assert!(!socket.exists(), "the socket outlived the daemon");
}

/// Spawning with captured output, for readers that run side by side.
trait SpawnCaptured {
    fn output_async(&mut self) -> Child;
}

impl SpawnCaptured for Command {
    fn output_async(&mut self) -> Child {
        self.stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    }
}
