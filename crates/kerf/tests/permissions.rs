//! The daemon and the CLI run as different users, with the built binaries: what a user
//! of another account is told (issue 25, item 6).
//!
//! iceoryx2 0.10 makes its files usable by their owner only, so the daemon's services are
//! the service user's. These tests start `kerfd` as an unprivileged user (uid 65534,
//! `nobody` on most systems) and check that `kerf status` as root and as another
//! unprivileged user (uid 65533, which needs no passwd entry) names the user the daemon
//! runs as, never invites to start a daemon and never shows a bare `InternalError`; that
//! without a daemon such a client is told to run as the service user; that root's
//! `kerf status` leaves no file of its own in the service user's tree; and that a
//! root-owned directory left in the daemon's tree stops the daemon with the path, the
//! owner and the fix.
//!
//! They switch users with `Command::uid`/`gid` (which also drops root's supplementary
//! groups), so they must run as root, as they do here and in CI; run as another user they
//! fail and say why, instead of passing without testing anything.
//!
//! Every test gets its own iceoryx2 tree, so that tests running in parallel (and other
//! test binaries, which use the default `/tmp/iceoryx2` as root) never meet: iceoryx2
//! reads `config/iceoryx2.toml` relative to the working directory first, and every
//! process here runs in the test's directory, whose file sets the root directory (a
//! directory owned by the daemon's user, mode 0750 as the package's tmpfiles entry makes
//! `/tmp/iceoryx2`) and a prefix of the shared-memory segments of its own. The directory
//! is under `/tmp` (not the target directory, which may sit in a home directory other
//! users cannot enter) and is removed on drop, with the test's segments in `/dev/shm`.

use std::fs;
use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const KERF: &str = env!("CARGO_BIN_EXE_kerf");
mod common;
use common::{Proc, kerfd};

/// The daemon's user.
const SERVICE_UID: u32 = 65534;
/// Another unprivileged user, without a passwd entry as a rule.
const OTHER_UID: u32 = 65533;
const ROOT_UID: u32 = 0;

/// Upper bound on any wait, so that a broken daemon fails a test instead of hanging it.
const PATIENCE: Duration = Duration::from_secs(30);
const POLL: Duration = Duration::from_millis(20);

/// The effective uid of this process.
fn euid() -> u32 {
    let status = fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("Uid:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|u| u.parse().ok())
        .expect("an effective uid in /proc/self/status")
}

/// Fails the test, saying why, unless it can start processes as other users.
fn require_root() {
    let uid = euid();
    assert!(
        uid == 0,
        "tests/permissions.rs starts kerfd and kerf as other users (uids {SERVICE_UID} and \
         {OTHER_UID}) and gives them directories, which needs root; this test runs as uid \
         {uid}. Run it as root (`sudo -E cargo test -p kerf --test permissions`, or in a \
         container as root, as CI does): it does not pass without testing."
    );
}

/// The name of user `uid` in /etc/passwd.
fn user_name(uid: u32) -> Option<String> {
    fs::read_to_string("/etc/passwd")
        .ok()?
        .lines()
        .find_map(|line| {
            let f: Vec<&str> = line.split(':').collect();
            (f.len() > 2 && f[2].parse() == Ok(uid)).then(|| f[0].to_string())
        })
}

/// How the messages name user `uid`: (``user `nobody` ``, `nobody`, `nobody`) or
/// (`uid 65534`, `'#65534'`, `65534`): label, `sudo -u` argument, plain name.
fn named(uid: u32) -> (String, String, String) {
    match user_name(uid) {
        Some(n) => (format!("user `{n}`"), n.clone(), n),
        None => (
            format!("uid {uid}"),
            format!("'#{uid}'"),
            format!("uid {uid}"),
        ),
    }
}

/// Starts `program ARGS` as `uid` (its own group too; no supplementary groups) in `dir`.
fn spawn(name: &str, dir: &Path, uid: u32, program: &str, args: &[&str]) -> Proc {
    let mut command = Command::new(program);
    command.args(args).current_dir(dir);
    if uid != euid() {
        command.uid(uid).gid(uid);
    }
    Proc::start(name, dir, command)
}

/// One test's machine and iceoryx2 tree.
struct Env {
    dir: PathBuf,
    /// The iceoryx2 root directory, owned by [`SERVICE_UID`].
    iox: PathBuf,
    /// The prefix of the tree's shared-memory segments.
    prefix: String,
    config_path: PathBuf,
    machine: String,
}

impl Env {
    fn new(tag: &str) -> Env {
        require_root();
        let machine = format!("p{}_{tag}", std::process::id());
        let dir = Path::new("/tmp").join(format!("kerf-permissions-{machine}"));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(dir.join("config")).unwrap();
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o755)).unwrap();
        let iox = dir.join("iceoryx2");
        fs::create_dir(&iox).unwrap();
        fs::set_permissions(&iox, fs::Permissions::from_mode(0o750)).unwrap();
        std::os::unix::fs::chown(&iox, Some(SERVICE_UID), Some(SERVICE_UID)).unwrap();
        let prefix = format!("kp{}{tag}_", std::process::id());
        fs::write(
            dir.join("config/iceoryx2.toml"),
            format!(
                "[global]\nroot-path = \"{}/\"\nprefix = \"{prefix}\"\n",
                iox.display()
            ),
        )
        .unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let text = kerf_testkit::config_text::without_homing(
            &fs::read_to_string(root.join("config/kerf.toml")).unwrap(),
        );
        assert!(text.contains("machine = \"default\""));
        let text = text.replacen(
            "machine = \"default\"",
            &format!("machine = \"{machine}\""),
            1,
        );
        let config_path = dir.join("kerf.toml");
        fs::write(&config_path, text).unwrap();
        Env {
            dir,
            iox,
            prefix,
            config_path,
            machine,
        }
    }

    fn config_arg(&self) -> &str {
        self.config_path.to_str().unwrap()
    }

    /// `kerf SUBCOMMAND --config C` as `uid`, to completion.
    fn kerf(&self, uid: u32, subcommand: &str) -> Output {
        static RUNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let name = format!("kerf-{subcommand}-{uid}-{n}");
        let mut p = spawn(
            &name,
            &self.dir,
            uid,
            KERF,
            &[subcommand, "--config", self.config_arg()],
        );
        let status = p.wait_within(PATIENCE);
        let out = Output {
            status,
            stdout: fs::read(&p.stdout).unwrap(),
            stderr: fs::read(&p.stderr).unwrap(),
        };
        let _ = fs::remove_file(&p.stdout);
        let _ = fs::remove_file(&p.stderr);
        out
    }

    fn spawn_daemon(&self, name: &str, uid: u32) -> Proc {
        spawn(
            name,
            &self.dir,
            uid,
            kerfd(),
            &["--config", self.config_arg()],
        )
    }

    /// Starts `kerfd` as `uid` and waits until `kerf status` of the same user answers.
    fn start_daemon(&self, name: &str, uid: u32) -> Proc {
        let mut d = self.spawn_daemon(name, uid);
        let deadline = Instant::now() + PATIENCE;
        loop {
            if let Some(status) = d.try_wait() {
                panic!("kerfd exited at start ({status}): {}", d.stderr());
            }
            let out = self.kerf(uid, "status");
            if out.status.success() {
                return d;
            }
            assert!(
                Instant::now() < deadline,
                "kerfd never answered its own user: {}\nkerf status: {}",
                d.stderr(),
                String::from_utf8_lossy(&out.stderr)
            );
            std::thread::sleep(POLL);
        }
    }

    /// Every path of the tree (and of its segments in /dev/shm) with an owner other than
    /// `uid`.
    fn owned_by_others(&self, uid: u32) -> Vec<(PathBuf, u32)> {
        fn walk(path: &Path, uid: u32, found: &mut Vec<(PathBuf, u32)>) {
            let Ok(meta) = fs::symlink_metadata(path) else {
                return;
            };
            if meta.uid() != uid {
                found.push((path.to_path_buf(), meta.uid()));
            }
            if meta.is_dir() {
                for entry in fs::read_dir(path).unwrap().flatten() {
                    walk(&entry.path(), uid, found);
                }
            }
        }
        let mut found = Vec::new();
        walk(&self.iox, uid, &mut found);
        for entry in fs::read_dir("/dev/shm").unwrap().flatten() {
            if entry
                .file_name()
                .to_string_lossy()
                .starts_with(&self.prefix)
            {
                walk(&entry.path(), uid, &mut found);
            }
        }
        found
    }

    /// `chown -R uid:uid` of the tree.
    fn give_tree_to(&self, uid: u32) {
        fn walk(path: &Path, uid: u32) {
            std::os::unix::fs::lchown(path, Some(uid), Some(uid)).unwrap();
            if fs::symlink_metadata(path).unwrap().is_dir() {
                for entry in fs::read_dir(path).unwrap().flatten() {
                    walk(&entry.path(), uid);
                }
            }
        }
        walk(&self.iox, uid);
    }
}

impl Drop for Env {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.dir);
        for entry in fs::read_dir("/dev/shm").into_iter().flatten().flatten() {
            if entry
                .file_name()
                .to_string_lossy()
                .starts_with(&self.prefix)
            {
                let _ = fs::remove_file(entry.path());
            }
        }
    }
}

/// Asserts that `out` failed with `wanted` on standard error and none of the messages
/// that mislead: the invitation to start a daemon, iceoryx2's bare error.
fn assert_told(out: &Output, who: &str, wanted: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "kerf status as {who} succeeded: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        stderr.contains(wanted),
        "kerf status as {who} did not say `{wanted}`:\n{stderr}"
    );
    for misleading in ["no kerfd answers", "start one", "InternalError"] {
        assert!(
            !stderr.contains(misleading),
            "kerf status as {who} said `{misleading}`:\n{stderr}"
        );
    }
}

#[test]
fn kerf_status_of_another_user_names_the_user_the_daemon_runs_as() {
    let env = Env::new("other");
    let _daemon = env.start_daemon("kerfd", SERVICE_UID);
    let (label, sudo, _) = named(SERVICE_UID);
    let wanted = format!(
        "kerfd for `{}` runs as {label}: run `sudo -u {sudo} kerf …`",
        env.machine
    );
    assert_told(&env.kerf(ROOT_UID, "status"), "root", &wanted);
    assert_told(&env.kerf(OTHER_UID, "status"), "uid 65533", &wanted);
    // Root asked first and left nothing of its own in the service user's tree (files of
    // root's there are what stopped the daemon in issue 25).
    assert_eq!(env.owned_by_others(SERVICE_UID), []);
    // The daemon still serves its own user.
    let out = env.kerf(SERVICE_UID, "status");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn without_a_daemon_a_tree_of_another_user_means_run_as_the_service_user() {
    let env = Env::new("stopped");
    let mut daemon = env.start_daemon("kerfd", SERVICE_UID);
    daemon.signal("TERM");
    let status = daemon.wait_within(PATIENCE);
    assert!(status.success(), "kerfd: {status}: {}", daemon.stderr());
    let service_user = match user_name(SERVICE_UID) {
        Some(n) => format!("`{n}`"),
        None => format!("(uid {SERVICE_UID})"),
    };
    let wanted =
        format!("permission denied: run as the service user {service_user} (see deploy/README.md)");
    assert_told(&env.kerf(ROOT_UID, "status"), "root", &wanted);
    assert_told(&env.kerf(OTHER_UID, "status"), "uid 65533", &wanted);
    assert_eq!(env.owned_by_others(SERVICE_UID), []);
}

#[test]
fn a_root_owned_directory_in_the_tree_stops_the_daemon_with_the_path_owner_and_fix() {
    for leftover in ["nodes", "services"] {
        let env = Env::new(&leftover[..1]);
        // What `sudo kerf run --embedded …` leaves when it runs first.
        let dir = env.iox.join(leftover);
        fs::create_dir(&dir).unwrap();
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o750)).unwrap();
        let mut daemon = env.spawn_daemon("kerfd-refused", SERVICE_UID);
        let status = daemon.wait_within(PATIENCE);
        let stderr = daemon.stderr();
        assert_eq!(status.code(), Some(1), "kerfd ({leftover}): {stderr}");
        let (_, _, plain) = named(SERVICE_UID);
        let chown = user_name(SERVICE_UID).unwrap_or_else(|| SERVICE_UID.to_string());
        let wanted = format!(
            "{} belongs to root, but kerfd runs as {plain}: run `sudo chown -R {chown}: {}`",
            dir.display(),
            env.iox.display()
        );
        assert!(
            stderr.contains(&wanted),
            "kerfd ({leftover}) did not say `{wanted}`:\n{stderr}"
        );
        assert!(!stderr.contains("InternalError"), "{stderr}");
        // The fix it names works.
        env.give_tree_to(SERVICE_UID);
        let _daemon = env.start_daemon("kerfd", SERVICE_UID);
    }
}
