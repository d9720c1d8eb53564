//! Who owns the iceoryx2 files of this PC, and what to tell a user whose process cannot
//! use them.
//!
//! iceoryx2 0.10 keeps a tree of files per PC: its root directory (`/tmp/iceoryx2` unless
//! an iceoryx2 configuration file says otherwise) with `nodes/` (one directory per node
//! plus its monitor files) and `services/` (one static file per service), and the shared
//! memory segments in `/dev/shm`, named with its prefix (`iox2_`). It creates every
//! directory 0750 and every file 0600 or 0400, owned by the effective user of the process
//! that created it. So the daemon's services can be used only by processes of the user it
//! runs as: another user's process fails with iceoryx2's bare `InternalError`; root gets
//! through the permissions, but the daemon cannot open the files root creates, so root's
//! requests go unanswered (and root's files left in the tree stop the daemon from starting).
//! This module finds out which of these happened and says what to do.
//!
//! Design decisions:
//! - Only diagnoses: it never changes an owner or removes a file. Giving the tree back to
//!   the service user is the tmpfiles entry's job (deploy/kerfd.tmpfiles) or the
//!   administrator's.
//! - The standard library only: the effective uid from `/proc/self/status`, user names
//!   from `/etc/passwd` (a user known only to NSS, LDAP for instance, shows as its uid).
//! - A daemon of another user is recognised from iceoryx2's own files where they are
//!   readable (root): the machine's control service file and a live `kerfd-control` node
//!   that holds it. Where they are not (another unprivileged user cannot even list the
//!   tree), from the running processes: a `kerfd` of the user who owns the tree whose
//!   configuration names the machine.
//! - A client asks [`client_refusal`] before it creates a node (three `stat` calls when
//!   all is well), so that root never leaves files in another user's tree.

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// Where the daemon's configuration lives when `kerfd` is started without `--config`.
const SYSTEM_CONFIG: &str = kerf_config::SYSTEM_CONFIG;

/// The name of the daemon's node that holds the control service (`kerfd-control`).
const DAEMON_CONTROL_NODE: &str = "kerfd-control";

/// The effective user id of this process (`None` where `/proc` does not tell).
pub(crate) fn effective_uid() -> Option<u32> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    proc_status_field(&status, "Uid:", 1)
}

/// Field `index` (0 real, 1 effective) of the line `key` of a `/proc/<pid>/status` text.
fn proc_status_field(status: &str, key: &str, index: usize) -> Option<u32> {
    let line = status.lines().find(|l| l.starts_with(key))?;
    line[key.len()..]
        .split_whitespace()
        .nth(index)?
        .parse()
        .ok()
}

/// The name of user `uid` in `/etc/passwd`.
pub fn user_name(uid: u32) -> Option<String> {
    let passwd = std::fs::read_to_string("/etc/passwd").ok()?;
    passwd_name(&passwd, uid)
}

fn passwd_name(passwd: &str, uid: u32) -> Option<String> {
    passwd.lines().find_map(|line| {
        let mut fields = line.split(':');
        let name = fields.next()?;
        let id: u32 = fields.nth(1)?.parse().ok()?;
        (id == uid && !name.is_empty()).then(|| name.to_string())
    })
}

/// A user as messages name it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct User {
    /// The user id.
    pub uid: u32,
    /// The name, if `/etc/passwd` has one.
    pub name: Option<String>,
}

impl User {
    /// User `uid`, named from `/etc/passwd`.
    pub fn of(uid: u32) -> User {
        User {
            uid,
            name: user_name(uid),
        }
    }

    /// `kerf`, or `uid 65533` for a user without a name.
    pub fn plain(&self) -> String {
        match &self.name {
            Some(n) => n.clone(),
            None => format!("uid {}", self.uid),
        }
    }

    /// ``user `kerf` ``, or `uid 65533`.
    pub fn label(&self) -> String {
        match &self.name {
            Some(n) => format!("user `{n}`"),
            None => format!("uid {}", self.uid),
        }
    }

    /// The argument of `sudo -u`: `kerf`, or `'#65533'` (quoted: `#` starts a comment).
    pub(crate) fn sudo_arg(&self) -> String {
        match &self.name {
            Some(n) => n.clone(),
            None => format!("'#{}'", self.uid),
        }
    }

    /// The owner argument of `chown`: `kerf`, or `65533`.
    pub(crate) fn chown_arg(&self) -> String {
        match &self.name {
            Some(n) => n.clone(),
            None => self.uid.to_string(),
        }
    }
}

/// The iceoryx2 tree of this process's iceoryx2 configuration.
#[derive(Debug, Clone)]
pub struct Tree {
    /// The root directory (`/tmp/iceoryx2`).
    pub root: PathBuf,
    /// The node directory (`/tmp/iceoryx2/nodes`).
    pub nodes: PathBuf,
    /// The service directory (`/tmp/iceoryx2/services`).
    pub services: PathBuf,
    /// Where the shared-memory segments are (`/dev/shm`).
    pub shm: PathBuf,
    /// The prefix of iceoryx2's file names (`iox2_`).
    pub prefix: String,
}

/// iceoryx2's root directory when no configuration file changes it.
pub(crate) const DEFAULT_ROOT: &str = "/tmp/iceoryx2";

impl Tree {
    /// The tree iceoryx2 uses in this process (its global configuration).
    pub fn current() -> Tree {
        // Before iceoryx2 reads its configuration, which it logs (as `ipc::node` does).
        set_log_level_from_env_or(LogLevel::Error);
        let global = &Config::global_config().global;
        let path = |p: &[u8]| -> PathBuf {
            // Without the trailing `/` of iceoryx2's paths.
            PathBuf::from(String::from_utf8_lossy(p).into_owned())
                .components()
                .collect()
        };
        Tree {
            root: path(global.root_path().as_bytes()),
            nodes: path(global.node_dir().as_bytes()),
            services: path(global.service_dir().as_bytes()),
            shm: PathBuf::from(super::SHM_DIR),
            prefix: String::from_utf8_lossy(global.prefix.as_bytes()).into_owned(),
        }
    }

    /// Whether this is iceoryx2's default tree, the one the package's tmpfiles entry
    /// gives to the service user.
    pub(crate) fn is_default(&self) -> bool {
        self.root == Path::new(DEFAULT_ROOT)
    }
}

/// A file or directory of the tree and its owner.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Owned {
    /// The path.
    pub path: PathBuf,
    /// The owner's uid.
    pub uid: u32,
}

/// The owner of `path` itself (a symbolic link is not followed), if it exists.
fn owner_of(path: &Path) -> Option<u32> {
    std::fs::symlink_metadata(path).ok().map(|m| m.uid())
}

/// The first of the tree's directories (root, `nodes/`, `services/`) that exists and
/// belongs to another user than `me`. A root directory that every user may write (mode
/// 1777, as `/tmp` itself) is shared by design and does not count.
pub(crate) fn foreign_directory(tree: &Tree, me: u32) -> Option<Owned> {
    [&tree.root, &tree.nodes, &tree.services]
        .into_iter()
        .find_map(|dir| {
            let meta = std::fs::symlink_metadata(dir).ok()?;
            let shared = dir == &tree.root && meta.mode() & 0o1002 == 0o1002;
            (meta.uid() != me && !shared).then(|| Owned {
                path: dir.clone(),
                uid: meta.uid(),
            })
        })
}

/// Every file and directory of the tree (the three directories, what `nodes/` and
/// `services/` hold, one level into each node's directory, and the shared-memory
/// segments with the tree's prefix) that belongs to another user than `me`, directories
/// first. Files that every user may read and write (iceoryx2's global management
/// segment) and a root directory every user may write (mode 1777) are left out: they
/// block no one.
pub(crate) fn foreign_entries(tree: &Tree, me: u32) -> Vec<Owned> {
    let mut found = Vec::new();
    let look = |path: &Path, found: &mut Vec<Owned>| {
        let Ok(meta) = std::fs::symlink_metadata(path) else {
            return;
        };
        let open_to_all = if meta.is_dir() {
            path == tree.root && meta.mode() & 0o1002 == 0o1002
        } else {
            meta.mode() & 0o006 == 0o006
        };
        if meta.uid() != me && !open_to_all {
            found.push(Owned {
                path: path.to_path_buf(),
                uid: meta.uid(),
            });
        }
    };
    let entries = |dir: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .collect();
        v.sort();
        v
    };
    for dir in [&tree.root, &tree.nodes, &tree.services] {
        look(dir, &mut found);
    }
    for dir in [&tree.nodes, &tree.services] {
        for path in entries(dir) {
            look(&path, &mut found);
            if path.is_dir() {
                for inner in entries(&path) {
                    look(&inner, &mut found);
                }
            }
        }
    }
    for path in entries(&tree.shm) {
        let ours = path
            .file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with(&tree.prefix));
        if ours && !tree.prefix.is_empty() {
            look(&path, &mut found);
        }
    }
    found.sort_by_key(|o| !o.path.is_dir());
    found
}

/// Why a daemon (`program`, running as this process's user) cannot use the iceoryx2
/// tree, with what to do: `None` when nothing of the tree belongs to another user (or
/// this process runs as root, whom permissions do not stop). For the daemon's failed
/// node or service creation; e.g. "/tmp/iceoryx2/nodes belongs to root, but kerfd runs as
/// kerf: run `sudo systemd-tmpfiles --create` or `sudo chown -R kerf: /tmp/iceoryx2`".
pub(crate) fn blocked_tree_message(program: &str) -> Option<String> {
    let me = effective_uid()?;
    if me == 0 {
        return None;
    }
    blocked_tree_message_in(&Tree::current(), program, me)
}

fn blocked_tree_message_in(tree: &Tree, program: &str, me: u32) -> Option<String> {
    let foreign = foreign_entries(tree, me);
    let first = foreign.first()?;
    let me_user = User::of(me);
    let owner = User::of(first.uid);
    let mut text = format!(
        "{} belongs to {}, but {program} runs as {}",
        first.path.display(),
        owner.plain(),
        me_user.plain()
    );
    if foreign.len() > 1 {
        let more = foreign.len() - 1;
        let (entries, belong) = if more == 1 {
            ("entry", "belongs")
        } else {
            ("entries", "belong")
        };
        text.push_str(&format!(
            " ({more} more {entries} of the iceoryx2 tree {belong} to other users)"
        ));
    }
    let chown = format!(
        "`sudo chown -R {}: {}`",
        me_user.chown_arg(),
        tree.root.display()
    );
    if first.path == tree.root && first.uid != 0 {
        // The tree is another (unprivileged) user's: that user is the service user.
        let run_as = format!(
            "run {program} as {} (`sudo -u {} {program} …`",
            owner.plain(),
            owner.sudo_arg()
        );
        if program == "kerfd" {
            text.push_str(&format!(
                ": {run_as}, or `systemctl start kerfd`), or make {} the owner of the tree with {chown}",
                me_user.plain()
            ));
        } else {
            text.push_str(&format!(": {run_as}; see deploy/README.md)"));
        }
    } else if tree.is_default() {
        text.push_str(&format!(
            ": run `sudo systemd-tmpfiles --create` or {chown}"
        ));
    } else {
        text.push_str(&format!(": run {chown}"));
    }
    if foreign.iter().any(|o| o.path.starts_with(&tree.shm)) {
        text.push_str(&format!(
            ", and `sudo chown {}: {}/{}*` for the shared memory",
            me_user.chown_arg(),
            tree.shm.display(),
            tree.prefix
        ));
    }
    Some(text)
}

/// What a client of `machine` must be told instead of trying, before it creates a node:
/// `Some` only when the tree belongs to another user (three `stat` calls otherwise). See
/// [`client_diagnosis`].
pub fn client_refusal(machine: &str) -> Option<String> {
    let me = effective_uid()?;
    let tree = Tree::current();
    foreign_directory(&tree, me)?;
    client_diagnosis_in(&tree, machine, me)
}

/// Why a client of `machine` that failed (no node, no service, no answer) failed, if the
/// cause is the owner of the iceoryx2 files:
///
/// - the machine's daemon runs as another user: "kerfd for `default` runs as user
///   `kerf`: run `sudo -u kerf kerf …`";
/// - the tree belongs to another user: "permission denied: run as the service user `kerf`
///   (see deploy/README.md); /tmp/iceoryx2 belongs to `kerf` and this command runs as
///   `alice`" (root's tree: to be given back to the service user).
///
/// `None` when neither holds: the failure has another cause.
pub fn client_diagnosis(machine: &str) -> Option<String> {
    let me = effective_uid()?;
    client_diagnosis_in(&Tree::current(), machine, me)
}

fn client_diagnosis_in(tree: &Tree, machine: &str, me: u32) -> Option<String> {
    if let Some(uid) = daemon_of_other_user(tree, machine, me) {
        let user = User::of(uid);
        return Some(format!(
            "kerfd for `{machine}` runs as {}: run `sudo -u {} kerf …`",
            user.label(),
            user.sudo_arg()
        ));
    }
    let foreign = foreign_directory(tree, me)?;
    let owner = User::of(foreign.uid);
    let me_user = User::of(me);
    if foreign.uid == 0 {
        // Root is nobody's service user: its files are the leftovers of a command run
        // with sudo, to be given back to the user kerfd runs as.
        // The tree's root is ours: the rest is to be given back to us; otherwise to the
        // user kerfd runs as, which only the administrator knows.
        let (user, whose) = if owner_of(&tree.root) == Some(me) {
            (me_user.chown_arg(), String::new())
        } else {
            (
                "USER".to_string(),
                " for the user kerfd runs as".to_string(),
            )
        };
        let chown = format!("`sudo chown -R {user}: {}`{whose}", tree.root.display());
        let fix = if tree.is_default() {
            format!("`sudo systemd-tmpfiles --create`, or {chown}")
        } else {
            chown
        };
        return Some(format!(
            "permission denied: {} belongs to root, and this command runs as {}: give the iceoryx2 tree back to the service user with {fix} (see deploy/README.md)",
            foreign.path.display(),
            me_user.plain()
        ));
    }
    let service_user = match &owner.name {
        Some(n) => format!("`{n}`"),
        None => format!("(uid {})", owner.uid),
    };
    Some(format!(
        "permission denied: run as the service user {service_user} (see deploy/README.md); {} belongs to {service_user} and this command runs as {}",
        foreign.path.display(),
        me_user.plain()
    ))
}

/// The uid of the live daemon of `machine`, if it runs as another user than `me`.
pub(crate) fn daemon_of_other_user(tree: &Tree, machine: &str, me: u32) -> Option<u32> {
    match std::fs::read_dir(&tree.services) {
        // Readable (root, or the tree's owner): iceoryx2's own records decide.
        Ok(_) => daemon_from_services(tree, machine, me),
        // Not readable: a `kerfd` process of the tree's owner that serves the machine.
        Err(_) => {
            let owner = foreign_directory(tree, me)?.uid;
            kerfd_processes()
                .into_iter()
                .find(|p| p.uid == owner && p.machine.as_deref() == Some(machine))
                .map(|p| p.uid)
        }
    }
}

/// From the tree: the control service file of `machine` belongs to another user than
/// `me`, and a live `kerfd-control` node of that user holds the service.
fn daemon_from_services(tree: &Tree, machine: &str, me: u32) -> Option<u32> {
    let name = kerf_proto::service_name(machine, kerf_proto::SERVICE_CONTROL).ok()?;
    let wanted = format!("service_name = \"{name}\"");
    let (hash, owner) = std::fs::read_dir(&tree.services)
        .ok()?
        .flatten()
        .find_map(|entry| {
            let text = std::fs::read_to_string(entry.path()).ok()?;
            text.lines().any(|l| l.trim() == wanted).then_some(())?;
            let hash = text.lines().find_map(|l| {
                l.trim()
                    .strip_prefix("service_hash = \"")?
                    .strip_suffix('"')
                    .map(str::to_string)
            })?;
            Some((hash, owner_of(&entry.path())?))
        })?;
    if owner == me {
        return None;
    }
    let tag = format!("{}{hash}.service_tag", tree.prefix);
    let mut alive = None;
    let _ = Node::<crate::ipc::Ipc>::list(Config::global_config(), |state| {
        if let NodeState::Alive(view) = &state {
            let is_control = view
                .details()
                .as_ref()
                .is_some_and(|d| d.name().as_str() == DAEMON_CONTROL_NODE);
            let dir = tree.nodes.join(view.id().value().to_string());
            if is_control && dir.join(&tag).exists() {
                alive = owner_of(&dir);
                return CallbackProgression::Stop;
            }
        }
        CallbackProgression::Continue
    });
    alive.filter(|&uid| uid != me)
}

/// A running `kerfd` process.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KerfdProcess {
    /// Its process id.
    pub pid: u32,
    /// Its effective uid.
    pub uid: u32,
    /// The machine its configuration names, if that could be read.
    pub machine: Option<String>,
}

/// The `kerfd` processes this process can see in `/proc`, with the machine each serves
/// (from its `--config` file, else `SYSTEM_CONFIG`, else the built-in machine).
pub(crate) fn kerfd_processes() -> Vec<KerfdProcess> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
        let Some(pid) = entry
            .file_name()
            .to_str()
            .and_then(|s| s.parse::<u32>().ok())
        else {
            continue;
        };
        let dir = entry.path();
        let Ok(status) = std::fs::read_to_string(dir.join("status")) else {
            continue;
        };
        let is_kerfd = status
            .lines()
            .find_map(|l| l.strip_prefix("Name:"))
            .is_some_and(|n| n.trim() == "kerfd");
        let Some(uid) = proc_status_field(&status, "Uid:", 1) else {
            continue;
        };
        if !is_kerfd {
            continue;
        }
        let cmdline = std::fs::read(dir.join("cmdline")).unwrap_or_default();
        let args: Vec<String> = cmdline
            .split(|&b| b == 0)
            .filter(|a| !a.is_empty())
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        let machine = config_of(&args, &dir).and_then(|c| machine_of(c.as_deref()));
        found.push(KerfdProcess { pid, uid, machine });
    }
    found
}

/// The configuration file named by `kerfd`'s arguments (`Some(None)`: none named),
/// relative names taken from the process's working directory `proc_dir/cwd`; `None` if
/// that cannot be read.
fn config_of(args: &[String], proc_dir: &Path) -> Option<Option<PathBuf>> {
    let mut named = None;
    let mut rest = args.iter().skip(1);
    while let Some(arg) = rest.next() {
        if arg == "--config" {
            named = rest.next().cloned();
        } else if let Some(v) = arg.strip_prefix("--config=") {
            named = Some(v.to_string());
        }
    }
    let Some(named) = named else {
        return Some(None);
    };
    let path = PathBuf::from(named);
    if path.is_absolute() {
        return Some(Some(path));
    }
    let cwd = std::fs::read_link(proc_dir.join("cwd")).ok()?;
    Some(Some(cwd.join(path)))
}

/// The machine a `kerfd` with configuration `config` serves (`None`: it could not be read).
fn machine_of(config: Option<&Path>) -> Option<String> {
    let path = match config {
        Some(p) => p.to_path_buf(),
        None if Path::new(SYSTEM_CONFIG).exists() => PathBuf::from(SYSTEM_CONFIG),
        None => return Some(kerf_config::Config::builtin().machine),
    };
    // Only the machine name, not `kerf_config::load_default`: that reads the tool table
    // and the parameter file too, which another user may not be allowed to read.
    let text = std::fs::read_to_string(path).ok()?;
    kerf_config::machine_name(&text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn passwd_names_and_missing_users() {
        let passwd = "root:x:0:0:root:/root:/bin/bash\nkerf:x:998:998::/:/usr/sbin/nologin\n";
        assert_eq!(passwd_name(passwd, 998).as_deref(), Some("kerf"));
        assert_eq!(passwd_name(passwd, 0).as_deref(), Some("root"));
        assert_eq!(passwd_name(passwd, 65533), None);
        let unnamed = User {
            uid: 65533,
            name: None,
        };
        assert_eq!(unnamed.label(), "uid 65533");
        assert_eq!(unnamed.sudo_arg(), "'#65533'");
        assert_eq!(unnamed.chown_arg(), "65533");
    }

    #[test]
    fn the_effective_uid_is_read_from_proc() {
        let status = "Name:\tkerfd\nUid:\t1000\t998\t998\t998\nGid:\t5\t5\t5\t5\n";
        assert_eq!(proc_status_field(status, "Uid:", 0), Some(1000));
        assert_eq!(proc_status_field(status, "Uid:", 1), Some(998));
        assert!(effective_uid().is_some());
    }

    #[test]
    fn the_config_of_a_kerfd_comes_from_its_arguments() {
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let proc_dir = Path::new("/proc/self");
        assert_eq!(
            config_of(&args(&["kerfd", "--config", "/etc/k.toml"]), proc_dir),
            Some(Some(PathBuf::from("/etc/k.toml")))
        );
        assert_eq!(
            config_of(&args(&["kerfd", "--config=/a/b.toml"]), proc_dir),
            Some(Some(PathBuf::from("/a/b.toml")))
        );
        assert_eq!(config_of(&args(&["kerfd"]), proc_dir), Some(None));
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(
            config_of(&args(&["kerfd", "--config", "k.toml"]), proc_dir),
            Some(Some(cwd.join("k.toml")))
        );
    }

    #[test]
    fn a_tree_of_this_user_has_nothing_foreign_and_the_message_names_the_first_entry() {
        let me = effective_uid().unwrap();
        let dir = std::env::temp_dir().join(format!("kerf-owner-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("nodes/12")).unwrap();
        std::fs::create_dir_all(dir.join("services")).unwrap();
        std::fs::create_dir_all(dir.join("shm")).unwrap();
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o750)).unwrap();
        let tree = Tree {
            root: dir.clone(),
            nodes: dir.join("nodes"),
            services: dir.join("services"),
            shm: dir.join("shm"),
            prefix: "kt_".to_string(),
        };
        assert_eq!(foreign_entries(&tree, me), []);
        assert_eq!(foreign_directory(&tree, me), None);
        assert_eq!(blocked_tree_message_in(&tree, "kerfd", me), None);
        // Seen as another user (uid `other`), every entry is foreign, directories first.
        let other = me.wrapping_add(4242);
        let found = foreign_entries(&tree, other);
        assert_eq!(found[0].path, dir);
        assert!(found.iter().all(|o| o.uid == me));
        assert!(found.iter().any(|o| o.path == dir.join("nodes/12")));
        assert_eq!(foreign_directory(&tree, other).unwrap().path, dir);
        let text = blocked_tree_message_in(&tree, "kerfd", other).unwrap();
        assert!(
            text.starts_with(&format!("{} belongs to ", dir.display())),
            "{text}"
        );
        assert!(
            text.contains(&format!("sudo chown -R {other}: {}`", dir.display())),
            "{text}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
