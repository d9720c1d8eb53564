//! Who owns an EtherCAT interface: one process at a time sends frames on it.
//!
//! The daemon cycling the bus and a commissioning command (`kerf ethercat scan`, `sdo`,
//! `exchange`) must never share an interface: the command's frames would disturb drives
//! the daemon commands every period, and two daemons would fight over them. So whoever
//! opens the raw socket first takes a [`Claim`] on the interface, and keeps it as long as
//! it uses the bus; a second [`Claim::take`] is refused with who holds it.
//!
//! The claim is a Unix domain socket bound in the abstract namespace as
//! `kerf-ethercat/<interface>` (shown as `@kerf-ethercat/<interface>` by `ss -xl`).
//! Abstract names belong to no file: the kernel releases them when the socket is closed,
//! also when its process is killed (no stale lock file after a SIGKILL). They are per
//! network namespace, as interfaces are. The holder also binds
//! `kerf-ethercat/<interface>/held-by/<holder>`, which names it for a refused contender;
//! the holder never accepts connections (no thread, nothing on the cycle's path).
//!
//! A refused contender connects to the claim's name (non-blocking, so a full backlog of
//! earlier contenders cannot make it wait) and reads the holder's process id from the
//! connection's peer credentials (`SO_PEERCRED`), then finds the holder's name of the
//! same process, or else the process's command name (`/proc/<pid>/comm`).

use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::linux::net::SocketAddrExt;
use std::os::unix::net::{SocketAddr, UnixListener};

use thiserror::Error;

/// The start of every claim's abstract socket name; the interface follows.
pub const NAME_PREFIX: &str = "kerf-ethercat/";

/// How often a take tries again when the name was released while it looked at its holder.
const ATTEMPTS: usize = 3;

/// Who holds (or wants) an interface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Holder {
    /// The daemon `kerfd`, cycling the bus.
    Daemon,
    /// A commissioning command, `kerf ethercat scan|sdo|exchange`.
    Commissioning,
}

impl Holder {
    /// Every holder, in the order a contender asks for them.
    const ALL: [Holder; 2] = [Holder::Daemon, Holder::Commissioning];

    /// The holder as messages name it: `kerfd`, `kerf ethercat`.
    pub fn name(self) -> &'static str {
        match self {
            Holder::Daemon => "kerfd",
            Holder::Commissioning => "kerf ethercat",
        }
    }

    /// The last part of the holder's abstract name.
    fn tag(self) -> &'static str {
        match self {
            Holder::Daemon => "kerfd",
            Holder::Commissioning => "kerf-ethercat",
        }
    }
}

/// Who was found holding an interface.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HeldBy {
    /// Kerf: the daemon or a commissioning command.
    Kerf(Holder),
    /// A process that holds the name without saying which Kerf program it is, by its
    /// command name (`/proc/<pid>/comm`).
    Process(String),
    /// Not found out (the holder lives in another PID namespace, or its listen queue is
    /// full of earlier contenders).
    Unknown,
}

/// Why an interface could not be claimed.
#[derive(Debug, Error)]
pub enum ClaimError {
    /// Another process (or this one) holds the interface.
    #[error("{}", in_use_text(.interface, *.wanted_by, .held_by, *.pid))]
    InUse {
        /// The interface.
        interface: String,
        /// Who asked for it.
        wanted_by: Holder,
        /// Who holds it.
        held_by: HeldBy,
        /// The holder's process id, where it could be found out.
        pid: Option<u32>,
    },
    /// The claim's socket could not be made (the name is too long for an abstract socket
    /// name, or the system refused a socket).
    #[error(
        "EtherCAT interface {interface}: cannot claim it (abstract socket @kerf-ethercat/{interface}): {source}"
    )]
    Socket {
        /// The interface.
        interface: String,
        /// The operating system's error.
        #[source]
        source: io::Error,
    },
}

/// The message of [`ClaimError::InUse`]: who holds the interface and what to do.
fn in_use_text(interface: &str, wanted_by: Holder, held_by: &HeldBy, pid: Option<u32>) -> String {
    let pid_text = pid.map(|p| format!(" (pid {p})")).unwrap_or_default();
    let head = format!("EtherCAT interface {interface} is in use by");
    match (held_by, wanted_by) {
        (HeldBy::Kerf(Holder::Daemon), Holder::Commissioning) => format!(
            "{head} kerfd{pid_text}: stop it first (systemctl stop kerfd) — commissioning commands must not disturb a running bus"
        ),
        (HeldBy::Kerf(Holder::Daemon), Holder::Daemon) => format!(
            "{head} kerfd{pid_text}: another daemon already runs this bus; stop it first (systemctl stop kerfd), or give each machine its own interface"
        ),
        (HeldBy::Kerf(Holder::Commissioning), _) => format!(
            "{head} kerf ethercat{pid_text}: a commissioning command is running on it; let it finish (or stop it), then try again"
        ),
        (HeldBy::Process(command), _) => format!(
            "{head} {command}{pid_text}, which holds Kerf's claim on it (@{NAME_PREFIX}{interface}): stop it first"
        ),
        (HeldBy::Unknown, _) => format!(
            "{head} another process{pid_text}, which holds Kerf's claim on it (@{NAME_PREFIX}{interface}; `ss -xlp | grep {NAME_PREFIX}{interface}` shows it): stop it first"
        ),
    }
}

/// The right to send frames on one interface, held until dropped.
#[derive(Debug)]
pub struct Claim {
    // Fields drop in order: the holder's name goes before the claim, so a holder's name
    // is never left behind a released claim.
    _named: Option<UnixListener>,
    _claim: UnixListener,
    interface: String,
    holder: Holder,
}

impl Claim {
    /// Claims `interface` for `holder`, or says who holds it. Binds one or two sockets;
    /// no thread, nothing to do while held.
    pub fn take(interface: &str, holder: Holder) -> Result<Claim, ClaimError> {
        let socket_error = |source| ClaimError::Socket {
            interface: interface.to_owned(),
            source,
        };
        let name = claim_name(interface);
        let address = SocketAddr::from_abstract_name(name.as_bytes()).map_err(socket_error)?;
        let mut last = (HeldBy::Unknown, None);
        for _ in 0..ATTEMPTS {
            match UnixListener::bind_addr(&address) {
                Ok(claim) => {
                    // Best effort: without it a contender still gets the process id
                    // and command name; it fails only while a killed holder's name is
                    // being released.
                    let named = SocketAddr::from_abstract_name(named_name(interface, holder))
                        .and_then(|a| UnixListener::bind_addr(&a))
                        .ok();
                    return Ok(Claim {
                        _named: named,
                        _claim: claim,
                        interface: interface.to_owned(),
                        holder,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AddrInUse => match held_by(interface) {
                    // Released meanwhile: try again.
                    Err(Released) => {}
                    Ok(found) => {
                        last = found;
                        break;
                    }
                },
                Err(e) => return Err(socket_error(e)),
            }
        }
        Err(ClaimError::InUse {
            interface: interface.to_owned(),
            wanted_by: holder,
            held_by: last.0,
            pid: last.1,
        })
    }

    /// The interface claimed.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// Who holds it: the one who took it.
    pub fn holder(&self) -> Holder {
        self.holder
    }
}

/// `kerf-ethercat/<interface>`.
fn claim_name(interface: &str) -> String {
    format!("{NAME_PREFIX}{interface}")
}

/// `kerf-ethercat/<interface>/held-by/<holder>`.
fn named_name(interface: &str, holder: Holder) -> String {
    format!("{NAME_PREFIX}{interface}/held-by/{}", holder.tag())
}

/// Nobody listens on the name any more.
struct Released;

/// Who holds the claim on `interface`, and their process id.
fn held_by(interface: &str) -> Result<(HeldBy, Option<u32>), Released> {
    let pid = match connect_abstract(claim_name(interface).as_bytes()) {
        Ok(connection) => peer_pid(&connection),
        Err(e) if e.raw_os_error() == Some(libc::ECONNREFUSED) => return Err(Released),
        // EAGAIN: the listen queue is full of earlier contenders.
        Err(_) => None,
    };
    let Some(pid) = pid else {
        return Ok((HeldBy::Unknown, None));
    };
    for holder in Holder::ALL {
        if let Ok(connection) = connect_abstract(named_name(interface, holder).as_bytes())
            && peer_pid(&connection) == Some(pid)
        {
            return Ok((HeldBy::Kerf(holder), Some(pid)));
        }
    }
    let held = match std::fs::read_to_string(format!("/proc/{pid}/comm")) {
        Ok(command) if !command.trim().is_empty() => HeldBy::Process(command.trim().to_owned()),
        _ => HeldBy::Unknown,
    };
    Ok((held, Some(pid)))
}

/// A stream socket connected to the abstract name `name`, without waiting: a listener
/// whose queue is full refuses at once (EAGAIN) instead of making the caller wait.
fn connect_abstract(name: &[u8]) -> io::Result<OwnedFd> {
    let mut address = libc::sockaddr_un {
        sun_family: libc::AF_UNIX as libc::sa_family_t,
        sun_path: [0; 108],
    };
    // The abstract namespace: a NUL, then the name (not NUL-terminated).
    let path = address
        .sun_path
        .get_mut(1..=name.len())
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "socket name too long"))?;
    for (to, from) in path.iter_mut().zip(name) {
        *to = *from as libc::c_char;
    }
    let length = std::mem::offset_of!(libc::sockaddr_un, sun_path) + 1 + name.len();
    // SAFETY: plain socket(2) call; the result is checked before use.
    let raw = unsafe {
        libc::socket(
            libc::AF_UNIX,
            libc::SOCK_STREAM | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
            0,
        )
    };
    if raw < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `raw` is a freshly opened descriptor that nothing else owns.
    let fd = unsafe { OwnedFd::from_raw_fd(raw) };
    // SAFETY: `address` is a valid `sockaddr_un` and `length` is within its size.
    let connected = unsafe {
        libc::connect(
            fd.as_raw_fd(),
            (&raw const address).cast::<libc::sockaddr>(),
            length as libc::socklen_t,
        )
    };
    if connected < 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(fd)
}

/// The process id of the listener at the other end of `connection` (`SO_PEERCRED`), as
/// this process's PID namespace sees it; `None` where it is not visible from here.
fn peer_pid(connection: &OwnedFd) -> Option<u32> {
    let mut credentials = libc::ucred {
        pid: 0,
        uid: 0,
        gid: 0,
    };
    let mut length = size_of::<libc::ucred>() as libc::socklen_t;
    // SAFETY: `credentials` is a writable `ucred` and `length` is its size.
    let got = unsafe {
        libc::getsockopt(
            connection.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_PEERCRED,
            (&raw mut credentials).cast::<libc::c_void>(),
            &raw mut length,
        )
    };
    if got < 0 {
        return None;
    }
    u32::try_from(credentials.pid).ok().filter(|&pid| pid != 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};

    /// The environment variable that makes [`holder_in_a_child_process`] hold a claim.
    const HOLD_ENV: &str = "KERF_CLAIM_TEST_HOLD";

    /// An interface name no other test (nor a daemon on this machine) uses: the
    /// abstract names are shared by every process of the network namespace.
    fn unique(tag: &str) -> String {
        format!("t{}{tag}", std::process::id())
    }

    fn in_use(e: ClaimError) -> (String, Holder, HeldBy, Option<u32>, String) {
        let text = e.to_string();
        match e {
            ClaimError::InUse {
                interface,
                wanted_by,
                held_by,
                pid,
            } => (interface, wanted_by, held_by, pid, text),
            other => panic!("expected the interface in use, got: {other}"),
        }
    }

    #[test]
    fn a_second_take_is_refused_naming_the_daemon_and_its_pid() {
        let interface = unique("a");
        let held = Claim::take(&interface, Holder::Daemon).expect("the first take");
        assert_eq!(held.interface(), interface);
        assert_eq!(held.holder(), Holder::Daemon);
        let e = Claim::take(&interface, Holder::Commissioning).expect_err("a second take");
        let pid = std::process::id();
        let (i, wanted, by, found_pid, text) = in_use(e);
        assert_eq!(i, interface);
        assert_eq!(wanted, Holder::Commissioning);
        assert_eq!(by, HeldBy::Kerf(Holder::Daemon));
        assert_eq!(found_pid, Some(pid));
        assert_eq!(
            text,
            format!(
                "EtherCAT interface {interface} is in use by kerfd (pid {pid}): stop it first (systemctl stop kerfd) — commissioning commands must not disturb a running bus"
            )
        );
        let e = Claim::take(&interface, Holder::Daemon).expect_err("a second daemon");
        assert_eq!(
            e.to_string(),
            format!(
                "EtherCAT interface {interface} is in use by kerfd (pid {pid}): another daemon already runs this bus; stop it first (systemctl stop kerfd), or give each machine its own interface"
            )
        );
    }

    #[test]
    fn a_commissioning_command_holding_the_interface_is_named() {
        let interface = unique("b");
        let _held = Claim::take(&interface, Holder::Commissioning).expect("the first take");
        let pid = std::process::id();
        for wanted in [Holder::Daemon, Holder::Commissioning] {
            let (_, _, by, found_pid, text) =
                in_use(Claim::take(&interface, wanted).expect_err("a second take"));
            assert_eq!(by, HeldBy::Kerf(Holder::Commissioning));
            assert_eq!(found_pid, Some(pid));
            assert_eq!(
                text,
                format!(
                    "EtherCAT interface {interface} is in use by kerf ethercat (pid {pid}): a commissioning command is running on it; let it finish (or stop it), then try again"
                )
            );
        }
    }

    #[test]
    fn a_process_holding_the_name_without_naming_itself_is_named_by_its_command() {
        let interface = unique("c");
        let address = SocketAddr::from_abstract_name(format!("kerf-ethercat/{interface}")).unwrap();
        let _foreign = UnixListener::bind_addr(&address).unwrap();
        let command = std::fs::read_to_string("/proc/self/comm").unwrap();
        let command = command.trim();
        let (_, _, by, pid, text) =
            in_use(Claim::take(&interface, Holder::Daemon).expect_err("a take"));
        assert_eq!(by, HeldBy::Process(command.to_owned()));
        assert_eq!(pid, Some(std::process::id()));
        assert!(
            text.starts_with(&format!(
                "EtherCAT interface {interface} is in use by {command} (pid {})",
                std::process::id()
            )),
            "{text}"
        );
    }

    #[test]
    fn a_dropped_claim_can_be_taken_again() {
        let interface = unique("d");
        let first = Claim::take(&interface, Holder::Commissioning).expect("the first take");
        drop(first);
        let second = Claim::take(&interface, Holder::Daemon).expect("a take after the drop");
        // And the new holder is the one named.
        let (_, _, by, _, _) =
            in_use(Claim::take(&interface, Holder::Commissioning).expect_err("a take while held"));
        assert_eq!(by, HeldBy::Kerf(Holder::Daemon));
        drop(second);
    }

    #[test]
    fn different_interfaces_do_not_conflict() {
        let a = Claim::take(&unique("e1"), Holder::Daemon).expect("one interface");
        let b = Claim::take(&unique("e2"), Holder::Daemon).expect("another interface");
        // A name that starts like another is another name.
        let c = Claim::take(&unique("e1x"), Holder::Commissioning).expect("a longer name");
        assert_eq!(
            [a.interface(), b.interface(), c.interface()],
            [unique("e1"), unique("e2"), unique("e1x")]
        );
    }

    #[test]
    fn a_name_too_long_for_a_socket_is_an_error_not_a_panic() {
        let long = "x".repeat(200);
        match Claim::take(&long, Holder::Daemon) {
            Err(ClaimError::Socket { interface, .. }) => assert_eq!(interface, long),
            other => panic!("expected a socket error, got {other:?}"),
        }
    }

    /// Not a test of its own: run by [`a_killed_holder_releases_the_interface`] in a
    /// child process, it takes the claim named in the environment, says so on standard
    /// output and waits to be killed (five minutes at most).
    #[test]
    #[ignore = "a helper process of a_killed_holder_releases_the_interface"]
    fn holder_in_a_child_process() {
        let interface = std::env::var(HOLD_ENV)
            .expect("run by a_killed_holder_releases_the_interface only, which sets it");
        let _claim = Claim::take(&interface, Holder::Daemon).expect("the child's take");
        // On a line of its own: libtest has printed the test's name without a newline.
        println!("\nholding {interface}");
        // Killed long before; the bound ends it should the parent have failed.
        std::thread::sleep(std::time::Duration::from_secs(300));
    }

    #[test]
    fn a_killed_holder_releases_the_interface() {
        let interface = unique("f");
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args([
                "--exact",
                "claim::tests::holder_in_a_child_process",
                "--ignored",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(HOLD_ENV, &interface)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let expected = format!("holding {interface}");
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        let said = lines.find(|l| l.as_ref().is_ok_and(|l| *l == expected));
        if said.is_none() {
            let _ = child.kill();
            let status = child.wait();
            panic!("the child never said {expected:?}; it ended with {status:?}");
        }
        let (_, _, by, pid, _) =
            in_use(Claim::take(&interface, Holder::Commissioning).expect_err("a take"));
        assert_eq!(by, HeldBy::Kerf(Holder::Daemon));
        assert_eq!(pid, Some(child.id()));
        child.kill().unwrap(); // SIGKILL: no destructor runs
        child.wait().unwrap();
        let claim = Claim::take(&interface, Holder::Commissioning)
            .expect("a take once the holder is killed");
        assert_eq!(claim.holder(), Holder::Commissioning);
    }
}
