//! The iceoryx2 services of one machine, opened the same way by the daemon and by every
//! client command: `kerf/<machine>/moves` (resolved moves, planner process → daemon),
//! `kerf/<machine>/setpoints` (one message per cycle, daemon → recorders and drives) and
//! `kerf/<machine>/control` (request/response: status, hold, resume, abort, override).
//!
//! Design decisions:
//! - The daemon creates the services (after removing what dead processes left behind) and
//!   is their only server and setpoint publisher; clients only open them. A client that
//!   cannot open a service has no daemon to talk to, and says so, unless the files belong
//!   to another user: then it names the user the daemon runs as ([`owner`]).
//! - Moves are never dropped: the subscriber's buffer holds the whole flow-control window
//!   plus a margin, and a publisher whose buffer is full waits instead of discarding.
//! - Setpoints are never waited for: a slow reader loses the oldest samples (safe
//!   overflow), sees the gap in the sequence numbers and reports it; the cycle never
//!   blocks.
//! - iceoryx2 installs no signal handlers of its own (the daemon and the commands handle
//!   SIGINT and SIGTERM themselves).
//! - iceoryx2's files can be used only by their owner ([`owner`]): a node or service that
//!   cannot be created because files of the tree belong to another user is reported with
//!   the path, the owner and what to do, never as iceoryx2's bare `InternalError`. The
//!   daemon's nodes are the ones named `kerfd-…` (`DAEMON_NODE_PREFIX`).

mod error;
pub mod owner;

pub use error::IpcError;

use std::time::Duration;

use iceoryx2::port::backpressure_strategy::BackpressureStrategy;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError::DoesNotExist as PubSubMissing;
use iceoryx2::service::builder::request_response::RequestResponseOpenError::DoesNotExist as ReqRespMissing;
use kerf_proto::{MoveMsg, Request, Response, SetpointMsg};

/// The iceoryx2 service type Kerf uses: inter-process, shared memory.
pub type Ipc = ipc::Service;

/// Samples a setpoint subscriber buffers: 16 s of cycles at 1 kHz. A reader that falls
/// further behind loses samples and reports the gap.
pub(crate) const SETPOINT_BUFFER: usize = 16_384;

/// Setpoint subscribers at once (recorders, `kerf run`, drive bridges).
pub(crate) const MAX_SETPOINT_SUBSCRIBERS: usize = 8;

/// Planner processes that may hold the moves service open at once (one streams; the
/// others are refused by the daemon's stream check until it ends).
pub(crate) const MAX_MOVE_PUBLISHERS: usize = 4;

/// Extra slots in the moves subscriber's buffer beyond the window (the BEGIN and END
/// messages and a margin).
pub(crate) const MOVE_BUFFER_MARGIN: usize = 64;

/// Clients of the control service at once.
pub(crate) const MAX_CONTROL_CLIENTS: usize = 16;

/// A node with iceoryx2's own signal handling off. iceoryx2's own log says only errors
/// (unless `IOX2_LOG_LEVEL` says otherwise): its notice that no iceoryx2 configuration
/// file exists is expected here, where the defaults are used on purpose.
///
/// Segments that a process killed while creating a service left empty are removed first
/// (`remove_unfinished_segments`): creating a node cleans up after dead nodes, and
/// opening such a segment there would wait forever.
///
/// A node that cannot be created because files of the iceoryx2 tree belong to another
/// user says which, whose, and what to do (`owner::blocked_tree_message`). The daemon's
/// first node (`DAEMON_FIRST_NODE`) also warns, once at start, of such files that did
/// not stop it (a dead root process's node it cannot clean up, for instance).
pub fn node(name: &str) -> Result<Node<ipc::Service>, IpcError> {
    set_log_level_from_env_or(LogLevel::Error);
    remove_unfinished_segments();
    let node_name = NodeName::new(name)
        .map_err(|e| IpcError::InvalidName(format!("node name `{name}`: {e:?}")))?;
    let program = if name.starts_with(DAEMON_NODE_PREFIX) {
        "kerfd"
    } else {
        "kerf"
    };
    let node = NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| match owner::blocked_tree_message(program) {
            Some(why) => IpcError::PermissionDenied {
                action: "cannot create an iceoryx2 node".to_string(),
                why,
            },
            None => IpcError::refused("cannot create an iceoryx2 node", e),
        })?;
    if name == DAEMON_FIRST_NODE
        && let Some(why) = owner::blocked_tree_message(program)
    {
        tracing::warn!("{why}");
    }
    Ok(node)
}

/// The names of the daemon's nodes start with this (`kerfd-control`, `kerfd-planning`,
/// `kerfd-publish`); clients' do not.
pub(crate) const DAEMON_NODE_PREFIX: &str = "kerfd-";

/// The daemon's first node, created once at its start.
pub(crate) const DAEMON_FIRST_NODE: &str = "kerfd-control";

/// Removes the shared-memory resources of dead processes (a daemon or client killed with
/// SIGKILL), so that a restarted daemon needs no manual clean-up. Returns how many dead
/// nodes were cleaned.
pub(crate) fn clean_dead_nodes() -> usize {
    set_log_level_from_env_or(LogLevel::Error);
    remove_unfinished_segments();
    let mut dead = Vec::new();
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(view) = state {
            dead.push(view);
        }
        CallbackProgression::Continue
    });
    let mut cleaned = 0;
    for view in dead {
        if view
            .blocking_remove_stale_resources(Duration::from_millis(500))
            .is_ok()
        {
            cleaned += 1;
        }
    }
    cleaned
}

/// Removes the static files of services whose creation never finished: a process killed
/// in the moment between creating a service's file and writing it leaves an empty file
/// that no dead node refers to, and the service could never be created again. Only
/// empty files older than [`UNFINISHED_AFTER`] are taken (a creation in progress writes
/// its file within microseconds). Returns how many were removed.
pub(crate) fn remove_unfinished_services() -> usize {
    let dir = Config::global_config().global.service_dir();
    let Ok(dir) = std::str::from_utf8(dir.as_bytes()).map(std::path::PathBuf::from) else {
        return 0;
    };
    remove_empty_files(&dir, "", "", false)
}

/// How old an empty service file must be to count as abandoned.
pub const UNFINISHED_AFTER: Duration = Duration::from_millis(100);

/// Where POSIX shared memory lives (iceoryx2's segments: `shm_open` names).
#[cfg(target_os = "linux")]
const SHM_DIR: &str = "/dev/shm";

/// Removes the shared-memory segments of services whose creation never finished: a
/// process killed in the moment between creating a service's dynamic segment and sizing
/// it leaves an empty segment. Opening it waits without end (iceoryx2 0.10 applies its
/// time-out to every state of a segment but an empty one), and every process that cleans
/// up after dead nodes opens it: creating a node does, so every later `kerf` command and
/// daemon start would hang. (A daemon test that kills starting daemons left one, and a
/// `kerf status` of another test hung in `Node::create`.)
///
/// Only empty segments with iceoryx2's prefix and its dynamic-segment suffix are taken,
/// once older than [`UNFINISHED_AFTER`]: a creation in progress sizes its segment within
/// microseconds. A younger empty one is waited for until it is that old (so at most that
/// long) and taken if it is still empty. Returns how many were removed.
pub(crate) fn remove_unfinished_segments() -> usize {
    #[cfg(target_os = "linux")]
    {
        let global = &Config::global_config().global;
        let text = |name: &[u8]| String::from_utf8_lossy(name).into_owned();
        let prefix = text(global.prefix.as_bytes());
        let suffix = text(global.service.dynamic_config_storage_suffix.as_bytes());
        remove_empty_files(std::path::Path::new(SHM_DIR), &prefix, &suffix, true)
    }
    #[cfg(not(target_os = "linux"))]
    {
        0
    }
}

/// Removes the empty files named `prefix…suffix` in `dir` that are older than
/// [`UNFINISHED_AFTER`]; with `wait_for_young`, a younger one is waited for until it is
/// that old and taken if it is still empty. Returns how many were removed.
fn remove_empty_files(
    dir: &std::path::Path,
    prefix: &str,
    suffix: &str,
    wait_for_young: bool,
) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if !(name.starts_with(prefix) && name.ends_with(suffix)) {
            continue;
        }
        let empty_age = |path: &std::path::Path| {
            let meta = std::fs::metadata(path).ok()?;
            (meta.is_file() && meta.len() == 0)
                .then(|| meta.modified().ok()?.elapsed().ok())
                .flatten()
        };
        let path = entry.path();
        let Some(age) = empty_age(&path) else {
            continue;
        };
        if !wait_for_young && age <= UNFINISHED_AFTER {
            continue;
        }
        if age < UNFINISHED_AFTER {
            std::thread::sleep(UNFINISHED_AFTER - age);
            if empty_age(&path).is_none() {
                continue;
            }
        }
        if std::fs::remove_file(&path).is_ok() {
            removed += 1;
        }
    }
    removed
}

fn service_name(machine: &str, which: &str) -> Result<ServiceName, IpcError> {
    let name = kerf_proto::service_name(machine, which)
        .map_err(|e| IpcError::InvalidName(e.to_string()))?;
    ServiceName::new(&name)
        .map_err(|e| IpcError::InvalidName(format!("service name `{name}`: {e:?}")))
}

/// An open refused because the service does not exist means that no daemon serves the
/// machine.
fn open_error(action: &str, does_not_exist: bool, e: impl std::fmt::Debug) -> IpcError {
    if does_not_exist {
        IpcError::NoService {
            action: action.to_string(),
        }
    } else {
        IpcError::refused(action, e)
    }
}
/// The moves service type.
pub type MovesService =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, MoveMsg, ()>;
/// The setpoints service type.
pub type SetpointsService =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, SetpointMsg, ()>;
/// The control service type.
pub type ControlService = iceoryx2::service::port_factory::request_response::PortFactory<
    ipc::Service,
    Request,
    (),
    Response,
    (),
>;

/// Creates the moves service (daemon): the subscriber's buffer holds `window` items plus
/// a margin; no history; never overflows.
pub fn create_moves(
    node: &Node<ipc::Service>,
    machine: &str,
    window: usize,
) -> Result<MovesService, IpcError> {
    let builder = || -> Result<_, IpcError> {
        Ok(node
            .service_builder(&service_name(machine, kerf_proto::SERVICE_MOVES)?)
            .publish_subscribe::<MoveMsg>()
            .max_publishers(MAX_MOVE_PUBLISHERS)
            .max_subscribers(1)
            .subscriber_max_buffer_size(window + MOVE_BUFFER_MARGIN)
            .history_size(0)
            .enable_safe_overflow(false))
    };
    repaired(machine, kerf_proto::SERVICE_MOVES, || {
        builder()?
            .open_or_create()
            .map_err(|e| IpcError::refused("cannot create the moves service", e))
    })
}

/// Opens the moves service (planner process).
pub fn open_moves(node: &Node<ipc::Service>, machine: &str) -> Result<MovesService, IpcError> {
    node.service_builder(&service_name(machine, kerf_proto::SERVICE_MOVES)?)
        .publish_subscribe::<MoveMsg>()
        .open()
        .map_err(|e| open_error("cannot open the moves service", e == PubSubMissing, e))
}

/// A publisher of moves that waits while the daemon's buffer is full (never drops).
pub fn move_publisher(
    service: &MovesService,
) -> Result<iceoryx2::port::publisher::Publisher<ipc::Service, MoveMsg, ()>, IpcError> {
    service
        .publisher_builder()
        .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
        .create()
        .map_err(|e| IpcError::refused("cannot publish moves", e))
}

/// The daemon's subscriber of moves.
pub fn move_subscriber(
    service: &MovesService,
    window: usize,
) -> Result<iceoryx2::port::subscriber::Subscriber<ipc::Service, MoveMsg, ()>, IpcError> {
    service
        .subscriber_builder()
        .buffer_size(window + MOVE_BUFFER_MARGIN)
        .create()
        .map_err(|e| IpcError::refused("cannot subscribe to moves", e))
}

/// Creates the setpoints service (daemon).
pub fn create_setpoints(
    node: &Node<ipc::Service>,
    machine: &str,
) -> Result<SetpointsService, IpcError> {
    repaired(machine, kerf_proto::SERVICE_SETPOINTS, || {
        node.service_builder(&service_name(machine, kerf_proto::SERVICE_SETPOINTS)?)
            .publish_subscribe::<SetpointMsg>()
            .max_publishers(1)
            .max_subscribers(MAX_SETPOINT_SUBSCRIBERS)
            .subscriber_max_buffer_size(SETPOINT_BUFFER)
            .history_size(0)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| IpcError::refused("cannot create the setpoints service", e))
    })
}

/// Opens the setpoints service (recorders).
pub fn open_setpoints(
    node: &Node<ipc::Service>,
    machine: &str,
) -> Result<SetpointsService, IpcError> {
    node.service_builder(&service_name(machine, kerf_proto::SERVICE_SETPOINTS)?)
        .publish_subscribe::<SetpointMsg>()
        .open()
        .map_err(|e| open_error("cannot open the setpoints service", e == PubSubMissing, e))
}

/// A subscriber of setpoints with the largest buffer.
pub fn setpoint_subscriber(
    service: &SetpointsService,
) -> Result<iceoryx2::port::subscriber::Subscriber<ipc::Service, SetpointMsg, ()>, IpcError> {
    service
        .subscriber_builder()
        .buffer_size(SETPOINT_BUFFER)
        .create()
        .map_err(|e| IpcError::refused("cannot subscribe to setpoints", e))
}

/// Creates the control service (daemon).
pub(crate) fn create_control(
    node: &Node<ipc::Service>,
    machine: &str,
) -> Result<ControlService, IpcError> {
    repaired(machine, kerf_proto::SERVICE_CONTROL, || {
        node.service_builder(&service_name(machine, kerf_proto::SERVICE_CONTROL)?)
            .request_response::<Request, Response>()
            .max_servers(1)
            .max_clients(MAX_CONTROL_CLIENTS)
            .open_or_create()
            .map_err(|e| IpcError::refused("cannot create the control service", e))
    })
}

/// Runs `build` (an open-or-create of one of the machine's services); if it fails, the
/// service's files are taken for the remains of a process killed while it created the
/// service (iceoryx2 then neither opens nor creates it, and no dead node refers to it):
/// they are removed and `build` runs once more. The daemon calls this only after the
/// control service showed that no other daemon serves the machine (or for the control
/// service itself, whose single server slot tells a live daemon apart).
fn repaired<T>(
    machine: &str,
    which: &str,
    build: impl Fn() -> Result<T, IpcError>,
) -> Result<T, IpcError> {
    let result = match build() {
        Ok(t) => Ok(t),
        Err(e) => {
            if remove_broken_service(machine, which) {
                tracing::warn!(
                    "removed the unusable remains of service kerf/{machine}/{which} ({e})"
                );
                build()
            } else {
                Err(e)
            }
        }
    };
    // Files of another user in the tree (a root-owned `services/`): say so, not iceoryx2's
    // `InternalError`.
    result.map_err(|e| match owner::blocked_tree_message("kerfd") {
        Some(why) => IpcError::PermissionDenied {
            action: format!("cannot create service kerf/{machine}/{which}"),
            why,
        },
        None => e,
    })
}

/// Removes the static file (and the shared memory) of the service `kerf/<machine>/<which>`.
fn remove_broken_service(machine: &str, which: &str) -> bool {
    let Ok(name) = kerf_proto::service_name(machine, which) else {
        return false;
    };
    let dir = Config::global_config().global.service_dir();
    let Ok(dir) = std::str::from_utf8(dir.as_bytes()).map(std::path::PathBuf::from) else {
        return false;
    };
    let wanted = format!("service_name = \"{name}\"");
    let mut removed = false;
    for entry in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        let Ok(text) = std::fs::read_to_string(entry.path()) else {
            continue;
        };
        if !text.lines().any(|l| l.trim() == wanted) {
            continue;
        }
        let hash = text.lines().find_map(|l| {
            l.trim()
                .strip_prefix("service_hash = \"")
                .and_then(|h| h.strip_suffix('"'))
                .map(str::to_string)
        });
        if std::fs::remove_file(entry.path()).is_ok() {
            removed = true;
        }
        // The service's shared memory is named after its hash.
        if let Some(hash) = hash.filter(|h| h.bytes().all(|b| b.is_ascii_hexdigit())) {
            for shm in std::fs::read_dir("/dev/shm")
                .into_iter()
                .flatten()
                .flatten()
            {
                if shm.file_name().to_string_lossy().contains(&hash) {
                    let _ = std::fs::remove_file(shm.path());
                }
            }
        }
    }
    removed
}

/// An event service (the control service's wake-ups).
pub type EventService = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

/// The two event services beside the control service: clients notify `request` after
/// sending a request, the daemon notifies `answer` after sending a response. They replace
/// polling at both ends (a request is taken and its answer seen within microseconds); the
/// daemon still looks for requests every 200 µs, so a client that does not
/// notify is answered too.
pub struct ControlEvents {
    /// `kerf/<machine>/control-request`.
    pub request: EventService,
    /// `kerf/<machine>/control-answer`.
    pub answer: EventService,
}

/// Creates the control event services (daemon): one listener (the daemon) and up to
/// [`MAX_CONTROL_CLIENTS`] notifiers on `request`, the reverse on `answer`.
pub(crate) fn create_control_events(
    node: &Node<ipc::Service>,
    machine: &str,
) -> Result<ControlEvents, IpcError> {
    let create = |which: &str, notifiers: usize, listeners: usize| {
        repaired(machine, which, || {
            node.service_builder(&service_name(machine, which)?)
                .event()
                .max_notifiers(notifiers)
                .max_listeners(listeners)
                .open_or_create()
                .map_err(|e| IpcError::refused("cannot create a control event service", e))
        })
    };
    Ok(ControlEvents {
        request: create(kerf_proto::SERVICE_CONTROL_REQUEST, MAX_CONTROL_CLIENTS, 1)?,
        answer: create(kerf_proto::SERVICE_CONTROL_ANSWER, 1, MAX_CONTROL_CLIENTS)?,
    })
}

/// Opens the control event services (clients).
pub fn open_control_events(
    node: &Node<ipc::Service>,
    machine: &str,
) -> Result<ControlEvents, IpcError> {
    let open = |which: &str| {
        node.service_builder(&service_name(machine, which)?)
            .event()
            .open()
            .map_err(|e| {
                open_error(
                    "cannot open a control event service",
                    e == iceoryx2::service::builder::event::EventOpenError::DoesNotExist,
                    e,
                )
            })
    };
    Ok(ControlEvents {
        request: open(kerf_proto::SERVICE_CONTROL_REQUEST)?,
        answer: open(kerf_proto::SERVICE_CONTROL_ANSWER)?,
    })
}

/// Opens the control service (clients).
pub fn open_control(node: &Node<ipc::Service>, machine: &str) -> Result<ControlService, IpcError> {
    node.service_builder(&service_name(machine, kerf_proto::SERVICE_CONTROL)?)
        .request_response::<Request, Response>()
        .open()
        .map_err(|e| open_error("cannot open the control service", e == ReqRespMissing, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_empty_segments_of_the_prefix_and_suffix_are_removed() {
        let dir = std::env::temp_dir().join(format!("kerf-ipc-empty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = [
            ("iox2_a_1.dynamic", &b""[..]),
            ("iox2_a_2.dynamic", &b"initialised"[..]),
            ("other_a_3.dynamic", &b""[..]),
            ("iox2_a_4.data", &b""[..]),
        ];
        for (name, text) in files {
            std::fs::write(dir.join(name), text).unwrap();
        }
        // Younger than UNFINISHED_AFTER: waited for, then taken while still empty.
        assert_eq!(remove_empty_files(&dir, "iox2_", ".dynamic", true), 1);
        let left: Vec<bool> = files.iter().map(|(n, _)| dir.join(n).exists()).collect();
        assert_eq!(left, [false, true, true, true]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_service_no_daemon_created_is_told_apart_from_other_failures() {
        let pid = std::process::id();
        let node = node(&format!("kerf-ipc-test-{pid}")).unwrap();
        let machine = format!("no-daemon-{pid}");
        let no_service = |r: Result<(), IpcError>| matches!(r, Err(IpcError::NoService { .. }));
        assert!(no_service(open_control(&node, &machine).map(|_| ())));
        assert!(no_service(open_moves(&node, &machine).map(|_| ())));
        assert!(no_service(open_setpoints(&node, &machine).map(|_| ())));
        // A name iceoryx2 or the protocol refuses is not "no daemon".
        let bad = open_control(&node, "not a machine name").map(|_| ());
        assert!(matches!(bad, Err(IpcError::InvalidName(_))), "{bad:?}");
    }
}
