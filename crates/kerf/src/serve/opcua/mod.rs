//! The OPC UA server of `kerf serve` (async-opcua): the machine as a `MachineToolType`
//! object of the Machinery `Machines` folder, laid out as the OPC UA for Machine Tools
//! companion specification (OPC 40501-1) lays it out as far as Kerf has the data
//! (docs/API.md, "OPC UA"), with the specifications' types imported from the OPC
//! Foundation's NodeSet2 files built into the binary, its values taken from the same
//! status the page shows, ten times a second.
//!
//! No variable is writable, so a client's write is refused by the server
//! (`BadNotWritable`). With a certificate configured (`serve.opcua_certificate`), the
//! server also offers secure endpoints where the configured users log in
//! (`serve.opcua_users`, passwords kept as salted PBKDF2 hashes); a user with the
//! operator role may call the `Control` object's methods: hold, resume and the overrides,
//! under the same control lease as the JSON API.

use std::net::SocketAddr;
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use kerf_config::{Config, OpcuaRole, OpcuaUser};
use kerf_proto::ControlCommand;
use opcua::crypto::{CertificateStore, SecurityPolicy};
use opcua::nodes::{AccessLevel, BaseEventType, MethodBuilder, ObjectBuilder, VariableBuilder};
use opcua::nodes::{ImportedItem, NodeSet2Import, NodeSetImport};
use opcua::server::authenticator::{AuthManager, Password, UserToken};
use opcua::server::node_manager::memory::{SimpleNodeManager, simple_node_manager_imports};
use opcua::server::{
    ANONYMOUS_USER_TOKEN_ID, ServerBuilder, ServerEndpoint, ServerHandle, SubscriptionCache,
};
use opcua::types::NodeSetNamespaceMapper;
use opcua::types::{
    Argument, ByteString, DataTypeId, DataValue, DateTime, Error as UaError, LocalizedText, NodeId,
    ObjectId, ObjectTypeId, QualifiedName, StatusCode, UAString, UserTokenPolicy, UserTokenType,
    Variant,
};
use serde_json::Value;
use tokio::sync::watch;

use super::jobs::{JobState, Jobs};
use super::lease::Lease;
use super::link::Ask;

mod control;
mod nodesets;

use control::{Users, control_methods};
use nodesets::imports;
pub use nodesets::{DI_NS, MACHINE_TOOL_NS, MACHINERY_NS};

/// How often the values are refreshed.
pub const REFRESH: Duration = Duration::from_millis(100);

/// The namespace of a machine's nodes: one per machine name, so that the servers of two
/// machines never share node ids.
pub fn namespace_uri(machine: &str) -> String {
    format!("urn:kerf:{machine}")
}

/// The server's application URI.
fn application_uri(machine: &str) -> String {
    format!("urn:kerf:serve:{machine}")
}

/// One variable the refresh writes: its node and where its value comes from.
struct Var {
    id: NodeId,
    value: fn(&Inputs) -> Variant,
}

/// What a refresh reads: the API's latest status object (null without a daemon) and
/// the current job.
struct Inputs<'a> {
    status: &'a Value,
    job: Option<&'a super::jobs::Job>,
    /// The Machine Tools namespace's index.
    mt_ns: u16,
}

/// The axes' names as the status has them.
const AXES: [&str; 6] = ["x", "y", "z", "a", "b", "c"];

/// The machine tool's operation mode (OPC 40501-1 MachineOperationMode): Automatic (1)
/// while a program runs or pauses, Setup (2) while an axis homes, Manual (0) otherwise
/// (Kerf has no mode switch: an idle machine takes jogs and MDI).
fn operation_mode(i: &Inputs) -> Variant {
    let state = i.status["state"].as_str().unwrap_or("");
    let homing = AXES
        .iter()
        .any(|a| !i.status["axes"][a]["homing"].is_null());
    let mode: i32 = match state {
        "running" | "holding" | "paused" | "starved" | "stopping" => 1,
        "manual" if homing => 2,
        _ => 0,
    };
    Variant::from(mode)
}

/// The channel's state (OPC 40501-1 ChannelState): 0 Active while a program moves,
/// 1 Interrupted while held, paused or faulted, 2 Reset otherwise.
fn channel_state(i: &Inputs) -> Variant {
    let state = i.status["state"].as_str().unwrap_or("");
    let value: i32 = match state {
        "running" | "starved" | "stopping" | "manual" => 0,
        "holding" | "paused" | "fault" => 1,
        _ => 2,
    };
    Variant::from(value)
}

/// The active program's progress, %: the line being executed of its lines while it runs,
/// 100 once it finished, 0 before the first program (an MDI line has none: 0).
fn progress(i: &Inputs) -> Variant {
    let percent = match i.job {
        Some(j) if j.kind == super::jobs::JobKind::Program => match j.state {
            JobState::Finished => 100.0,
            _ if j.lines == 0 => 0.0,
            _ => {
                let line = i.status["line"].as_f64().unwrap_or(0.0);
                (line / f64::from(j.lines) * 100.0).clamp(0.0, 100.0)
            }
        },
        _ => 0.0,
    };
    Variant::from(percent)
}

/// The active program's state in ProductionProgramStateMachineType: its name and the
/// state's node (in the Machine Tools namespace): "Running" while its job runs and the
/// machine moves it, "Interrupted" while held or paused, "Ended" when it finished,
/// "Aborted" when it failed, "Initializing" before the first.
fn program_state(i: &Inputs) -> (&'static str, u32) {
    let state = i.status["state"].as_str().unwrap_or("");
    match i.job.map(|j| j.state) {
        None => ("Initializing", mt::INITIALIZING),
        Some(JobState::Finished) => ("Ended", mt::ENDED),
        Some(JobState::Failed) => ("Aborted", mt::ABORTED),
        Some(JobState::Running) if matches!(state, "holding" | "paused" | "fault") => {
            ("Interrupted", mt::INTERRUPTED)
        }
        Some(JobState::Running) => ("Running", mt::RUNNING),
    }
}

/// What the OPC UA server needs of `kerf serve`: the status and jobs it shows, where its
/// control methods' requests go and the control lease they are under.
pub struct Feeds {
    /// The latest status message.
    pub status: watch::Receiver<Arc<String>>,
    /// The jobs (the active program).
    pub jobs: Jobs,
    /// Control requests to the link.
    pub asks: Sender<Ask>,
    /// Who controls the machine.
    pub lease: Arc<Mutex<Lease>>,
}

/// The endpoints offered with a certificate, besides None: signed and encrypted, with the
/// policies the OPC UA specification does not deprecate.
fn secure_endpoints() -> Vec<(&'static str, ServerEndpoint)> {
    let ids = [ANONYMOUS_USER_TOKEN_ID.to_string()];
    vec![
        (
            "basic256sha256_sign_encrypt",
            ServerEndpoint::new_basic256sha256_sign_encrypt("/", &ids),
        ),
        (
            "aes128_sha256_rsaoaep_sign_encrypt",
            ServerEndpoint::new_aes128_sha256_rsaoaep_sign_encrypt("/", &ids),
        ),
        (
            "aes256_sha256_rsapss_sign_encrypt",
            ServerEndpoint::new_aes256_sha256_rsapss_sign_encrypt("/", &ids),
        ),
    ]
}

/// Starts the OPC UA server of `config`'s machine on `listener`, fed from `feeds`;
/// returns its handle (cancel it to stop the server). Fails when the configured
/// certificate or its key cannot be read.
pub async fn start(
    config: &Config,
    listener: tokio::net::TcpListener,
    feeds: Feeds,
) -> Result<ServerHandle, String> {
    let addr: SocketAddr = listener.local_addr().map_err(|e| e.to_string())?;
    let machine = config.machine.clone();
    let ns_uri = namespace_uri(&machine);
    let mut builder = ServerBuilder::new_anonymous(format!("Kerf {machine}"))
        .application_uri(application_uri(&machine))
        .product_uri("urn:kerf")
        .host(addr.ip().to_string())
        .port(addr.port())
        .default_endpoint("none")
        .create_sample_keypair(false)
        .with_authenticator(Arc::new(Users {
            users: config.serve.opcua_users.clone(),
        }));
    match (
        &config.serve.opcua_certificate,
        &config.serve.opcua_private_key,
    ) {
        (Some(cert), Some(key)) => {
            // Read here first: the server itself would go on without them, offering
            // endpoints nobody can use.
            CertificateStore::read_cert(cert)
                .map_err(|e| format!("the certificate {}: {e}", cert.display()))?;
            CertificateStore::read_pkey(key)
                .map_err(|e| format!("the private key {}: {e}", key.display()))?;
            builder = builder
                .certificate_path(cert)
                .private_key_path(key)
                .pki_dir(config.machine_opcua_pki_directory());
            for (id, endpoint) in secure_endpoints() {
                builder = builder.add_endpoint(id, endpoint);
            }
        }
        _ => {
            builder =
                builder.pki_dir(std::env::temp_dir().join(format!("kerf-serve-pki-{machine}")));
        }
    }
    let (server, handle) = builder
        .with_node_manager(simple_node_manager_imports(imports(&ns_uri), "kerf"))
        .build()?;
    let manager = handle
        .node_managers()
        .get_of_type::<SimpleNodeManager>()
        .ok_or("no node manager")?;
    let index = |uri: &str| {
        handle
            .get_namespace_index(uri)
            .ok_or_else(|| format!("no namespace index of {uri}"))
    };
    let spaces = Spaces {
        own: index(&ns_uri)?,
        mt: index(MACHINE_TOOL_NS)?,
        machinery: index(MACHINERY_NS)?,
        di: index(DI_NS)?,
    };
    let (machine_id, vars) = address_space(config, &manager, spaces);
    control_methods(config, &manager, spaces.own, &feeds);
    let subscriptions = handle.subscriptions().clone();
    tokio::spawn(async move {
        if let Err(e) = server.run_with(listener).await {
            eprintln!("kerf serve: the OPC UA server stopped: {e}");
        }
    });
    tokio::spawn(refresh(
        manager,
        subscriptions,
        vars,
        machine_id,
        machine,
        feeds.status,
        feeds.jobs,
        handle.clone(),
        spaces.mt,
    ));
    Ok(handle)
}

/// The namespace indexes the address space uses.
#[derive(Clone, Copy)]
struct Spaces {
    /// The machine's own.
    own: u16,
    /// Machines Tools.
    mt: u16,
    /// Machinery.
    machinery: u16,
    /// Devices.
    di: u16,
}

/// Machine Tools type ids (OPC 40501-1's NodeSet2: `ns=MachineTool;i=N`).
mod mt {
    pub const MACHINE_TOOL_TYPE: u32 = 13;
    pub const IDENTIFICATION_TYPE: u32 = 11;
    pub const MONITORING_TYPE: u32 = 14;
    pub const MACHINE_OPERATION_MONITORING_TYPE: u32 = 26;
    pub const CHANNEL_MONITORING_TYPE: u32 = 16;
    pub const SPINDLE_MONITORING_TYPE: u32 = 22;
    pub const PRODUCTION_TYPE: u32 = 21;
    pub const PRODUCTION_ACTIVE_PROGRAM_TYPE: u32 = 32;
    pub const PRODUCTION_PROGRAM_STATE_MACHINE_TYPE: u32 = 15;
    pub const NOTIFICATION_TYPE: u32 = 7;
    pub const EQUIPMENT_TYPE: u32 = 12;
    pub const MACHINE_OPERATION_MODE: u32 = 65;
    pub const CHANNEL_STATE: u32 = 64;
    /// The states of ProductionProgramStateMachineType.
    pub const INITIALIZING: u32 = 5039;
    pub const RUNNING: u32 = 5041;
    pub const ENDED: u32 = 5038;
    pub const INTERRUPTED: u32 = 5040;
    pub const ABORTED: u32 = 5037;
}

/// The Machinery `Machines` folder (OPC 40001-1), `ns=Machinery;i=1001`.
const MACHINES_FOLDER: u32 = 1001;

/// Builds the machine's nodes; the machine object's id and the variables to refresh.
fn address_space(config: &Config, manager: &SimpleNodeManager, sp: Spaces) -> (NodeId, Vec<Var>) {
    let machine = &config.machine;
    let ns = sp.own;
    let id = |path: &str| NodeId::new(ns, format!("{machine}.{path}"));
    let mut vars = Vec::new();
    let mut space = manager.address_space().write();
    let root = NodeId::new(ns, machine.as_str());
    ObjectBuilder::new(&root, QualifiedName::new(ns, machine), machine.as_str())
        .organized_by(NodeId::new(sp.machinery, MACHINES_FOLDER))
        .has_type_definition(NodeId::new(sp.mt, mt::MACHINE_TOOL_TYPE))
        .event_notifier(opcua::nodes::EventNotifier::SUBSCRIBE_TO_EVENTS)
        .insert(&mut *space);
    // An object `path` (its last word the display name) named `browse`, of type `type_id`.
    let object = |space: &mut opcua::server::address_space::AddressSpace,
                  path: &str,
                  browse: QualifiedName,
                  parent: &NodeId,
                  type_id: NodeId| {
        let node = id(path);
        let leaf = path.rsplit('.').next().unwrap_or(path);
        ObjectBuilder::new(&node, browse, leaf)
            .component_of(parent.clone())
            .has_type_definition(type_id)
            .insert(space);
        node
    };
    let base = || NodeId::from(ObjectTypeId::BaseObjectType);
    let constant = |space: &mut opcua::server::address_space::AddressSpace,
                    path: &str,
                    parent: &NodeId,
                    value: Variant,
                    data_type: DataTypeId| {
        let leaf = path.rsplit('.').next().unwrap_or(path);
        VariableBuilder::new(&id(path), QualifiedName::new(sp.di, leaf), leaf)
            .property_of(parent.clone())
            .data_type(data_type)
            .value(value)
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .insert(space);
    };
    let mut variable = |space: &mut opcua::server::address_space::AddressSpace,
                        path: &str,
                        browse_ns: u16,
                        parent: &NodeId,
                        data_type: NodeId,
                        initial: Variant,
                        value: fn(&Inputs) -> Variant| {
        let leaf = path.rsplit('.').next().unwrap_or(path);
        let node = id(path);
        VariableBuilder::new(&node, QualifiedName::new(browse_ns, leaf), leaf)
            .component_of(parent.clone())
            .data_type(data_type)
            .value(initial)
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .insert(space);
        vars.push(Var { id: node, value });
    };
    // Identification (DI's browse names).
    let identification = object(
        &mut space,
        "Identification",
        QualifiedName::new(sp.di, "Identification"),
        &root,
        NodeId::new(sp.mt, mt::IDENTIFICATION_TYPE),
    );
    let s = &config.serve;
    let serial = if s.serial_number.is_empty() {
        machine.as_str()
    } else {
        s.serial_number.as_str()
    };
    for (path, value, data_type) in [
        (
            "Identification.Manufacturer",
            Variant::from(LocalizedText::from(s.manufacturer.as_str())),
            DataTypeId::LocalizedText,
        ),
        (
            "Identification.Model",
            Variant::from(LocalizedText::from(s.model.as_str())),
            DataTypeId::LocalizedText,
        ),
        (
            "Identification.SerialNumber",
            Variant::from(UAString::from(serial)),
            DataTypeId::String,
        ),
        (
            "Identification.ProductInstanceUri",
            Variant::from(UAString::from(format!("urn:kerf:{machine}"))),
            DataTypeId::String,
        ),
        (
            "Identification.SoftwareRevision",
            Variant::from(UAString::from(env!("CARGO_PKG_VERSION"))),
            DataTypeId::String,
        ),
    ] {
        constant(&mut space, path, &identification, value, data_type);
    }
    // Monitoring.
    let monitoring = object(
        &mut space,
        "Monitoring",
        QualifiedName::new(sp.mt, "Monitoring"),
        &root,
        NodeId::new(sp.mt, mt::MONITORING_TYPE),
    );
    let tool = object(
        &mut space,
        "Monitoring.MachineTool",
        QualifiedName::new(sp.mt, "MachineTool"),
        &monitoring,
        NodeId::new(sp.mt, mt::MACHINE_OPERATION_MONITORING_TYPE),
    );
    variable(
        &mut space,
        "Monitoring.MachineTool.OperationMode",
        sp.mt,
        &tool,
        NodeId::new(sp.mt, mt::MACHINE_OPERATION_MODE),
        Variant::from(0i32),
        operation_mode,
    );
    variable(
        &mut space,
        "Monitoring.MachineTool.PowerOnDuration",
        sp.mt,
        &tool,
        DataTypeId::UInt32.into(),
        Variant::from(0u32),
        |i| {
            // Hours the daemon has run: its cycles times its period.
            let cycles = i.status["cycles"].as_f64().unwrap_or(0.0);
            let period_us = i.status["period_us"].as_f64().unwrap_or(0.0);
            Variant::from((cycles * period_us / 3.6e9) as u32)
        },
    );
    let channel = object(
        &mut space,
        "Monitoring.Channel1",
        QualifiedName::new(ns, "Channel1"),
        &monitoring,
        NodeId::new(sp.mt, mt::CHANNEL_MONITORING_TYPE),
    );
    variable(
        &mut space,
        "Monitoring.Channel1.ChannelState",
        sp.mt,
        &channel,
        NodeId::new(sp.mt, mt::CHANNEL_STATE),
        Variant::from(2i32),
        channel_state,
    );
    variable(
        &mut space,
        "Monitoring.Channel1.FeedOverride",
        sp.mt,
        &channel,
        DataTypeId::Double.into(),
        Variant::from(100.0),
        |i| Variant::from(i.status["override_pct"].as_f64().unwrap_or(0.0)),
    );
    let spindle = object(
        &mut space,
        "Monitoring.Spindle",
        QualifiedName::new(ns, "Spindle"),
        &monitoring,
        NodeId::new(sp.mt, mt::SPINDLE_MONITORING_TYPE),
    );
    variable(
        &mut space,
        "Monitoring.Spindle.Override",
        sp.mt,
        &spindle,
        DataTypeId::Double.into(),
        Variant::from(100.0),
        |i| {
            Variant::from(
                i.status["spindle"]["override_pct"]
                    .as_f64()
                    .unwrap_or(100.0),
            )
        },
    );
    variable(
        &mut space,
        "Monitoring.Spindle.IsRotating",
        sp.mt,
        &spindle,
        DataTypeId::Boolean.into(),
        Variant::from(false),
        |i| {
            Variant::from(
                i.status["spindle"]["actual_rpm"]
                    .as_f64()
                    .is_some_and(|r| r.abs() > 0.5),
            )
        },
    );
    // The axes: Kerf's own (the specification has no axis monitoring).
    let present = config.axes.present();
    let position: [fn(&Inputs) -> Variant; 6] = [
        |i| Variant::from(i.status["position"]["x"].as_f64().unwrap_or(0.0)),
        |i| Variant::from(i.status["position"]["y"].as_f64().unwrap_or(0.0)),
        |i| Variant::from(i.status["position"]["z"].as_f64().unwrap_or(0.0)),
        |i| Variant::from(i.status["position"]["a"].as_f64().unwrap_or(0.0)),
        |i| Variant::from(i.status["position"]["b"].as_f64().unwrap_or(0.0)),
        |i| Variant::from(i.status["position"]["c"].as_f64().unwrap_or(0.0)),
    ];
    for (k, axis) in AXES.iter().enumerate() {
        if !present[k] {
            continue;
        }
        let upper = axis.to_ascii_uppercase();
        let node = object(
            &mut space,
            &format!("Monitoring.{upper}"),
            QualifiedName::new(ns, upper.as_str()),
            &monitoring,
            base(),
        );
        variable(
            &mut space,
            &format!("Monitoring.{upper}.ActualPosition"),
            ns,
            &node,
            DataTypeId::Double.into(),
            Variant::from(0.0),
            position[k],
        );
    }
    // Production.
    let production = object(
        &mut space,
        "Production",
        QualifiedName::new(sp.mt, "Production"),
        &root,
        NodeId::new(sp.mt, mt::PRODUCTION_TYPE),
    );
    let program = object(
        &mut space,
        "Production.ActiveProgram",
        QualifiedName::new(sp.mt, "ActiveProgram"),
        &production,
        NodeId::new(sp.mt, mt::PRODUCTION_ACTIVE_PROGRAM_TYPE),
    );
    variable(
        &mut space,
        "Production.ActiveProgram.Name",
        sp.mt,
        &program,
        DataTypeId::String.into(),
        Variant::from(UAString::from("")),
        |i| {
            Variant::from(UAString::from(match i.job {
                None => String::new(),
                Some(j) if j.kind == super::jobs::JobKind::Mdi => format!("MDI: {}", j.name),
                Some(j) => j.name.clone(),
            }))
        },
    );
    variable(
        &mut space,
        "Production.ActiveProgram.Line",
        ns,
        &program,
        DataTypeId::UInt32.into(),
        Variant::from(0u32),
        |i| Variant::from(i.status["line"].as_u64().unwrap_or(0) as u32),
    );
    variable(
        &mut space,
        "Production.ActiveProgram.Progress",
        ns,
        &program,
        DataTypeId::Double.into(),
        Variant::from(0.0),
        progress,
    );
    let state = object(
        &mut space,
        "Production.ActiveProgram.State",
        QualifiedName::new(sp.mt, "State"),
        &program,
        NodeId::new(sp.mt, mt::PRODUCTION_PROGRAM_STATE_MACHINE_TYPE),
    );
    let current = id("Production.ActiveProgram.State.CurrentState");
    VariableBuilder::new(
        &current,
        QualifiedName::new(0, "CurrentState"),
        "CurrentState",
    )
    .component_of(state.clone())
    .data_type(DataTypeId::LocalizedText)
    .value(LocalizedText::from("Initializing"))
    .access_level(AccessLevel::CURRENT_READ)
    .user_access_level(AccessLevel::CURRENT_READ)
    .insert(&mut *space);
    vars.push(Var {
        id: current.clone(),
        value: |i| Variant::from(LocalizedText::from(program_state(i).0)),
    });
    let state_id = id("Production.ActiveProgram.State.CurrentState.Id");
    VariableBuilder::new(&state_id, QualifiedName::new(0, "Id"), "Id")
        .property_of(current)
        .data_type(DataTypeId::NodeId)
        .value(NodeId::new(sp.mt, mt::INITIALIZING))
        .access_level(AccessLevel::CURRENT_READ)
        .user_access_level(AccessLevel::CURRENT_READ)
        .insert(&mut *space);
    let state_ids = Var {
        id: state_id,
        value: |i| Variant::from(NodeId::new(i.mt_ns, program_state(i).1)),
    };
    vars.push(state_ids);
    // Notification (the faults' events are raised on the machine) and Equipment (none
    // described yet): present, as the type has them.
    object(
        &mut space,
        "Notification",
        QualifiedName::new(sp.mt, "Notification"),
        &root,
        NodeId::new(sp.mt, mt::NOTIFICATION_TYPE),
    );
    object(
        &mut space,
        "Equipment",
        QualifiedName::new(sp.mt, "Equipment"),
        &root,
        NodeId::new(sp.mt, mt::EQUIPMENT_TYPE),
    );
    (root, vars)
}

/// Refreshes every variable from the latest status and job every [`REFRESH`], and raises
/// an event on the machine object at each new fault (its text as the message).
#[allow(clippy::too_many_arguments)]
async fn refresh(
    manager: Arc<SimpleNodeManager>,
    subscriptions: Arc<SubscriptionCache>,
    vars: Vec<Var>,
    machine_id: NodeId,
    machine: String,
    status: watch::Receiver<Arc<String>>,
    jobs: Jobs,
    handle: ServerHandle,
    mt_ns: u16,
) {
    let mut tick = tokio::time::interval(REFRESH);
    let mut last_fault: Option<String> = None;
    let mut events = 0u64;
    while !handle.token().is_cancelled() {
        tick.tick().await;
        let latest = status.borrow().clone();
        let message: Value = serde_json::from_str(&latest).unwrap_or_default();
        let job = jobs.current();
        let inputs = Inputs {
            status: &message["status"],
            job: job.as_ref(),
            mt_ns,
        };
        let now = DateTime::now();
        let values: Vec<(&NodeId, Option<&opcua::types::NumericRange>, DataValue)> = vars
            .iter()
            .map(|v| (&v.id, None, DataValue::new_at((v.value)(&inputs), now)))
            .collect();
        let _ = manager.set_values(&subscriptions, values.into_iter());
        let fault = message["status"]["fault"].as_str().map(str::to_owned);
        if fault.is_some() && fault != last_fault {
            events += 1;
            let event = BaseEventType::new_now(
                ObjectTypeId::BaseEventType,
                ByteString::from(format!("{machine}-{events}").into_bytes()),
                LocalizedText::from(fault.clone().unwrap_or_default().as_str()),
            )
            .set_source_node(machine_id.clone())
            .set_source_name(UAString::from(machine.as_str()))
            .set_severity(800);
            let server = NodeId::from(ObjectId::Server);
            let raised: &dyn opcua::nodes::Event = &event;
            subscriptions.notify_events([(raised, &machine_id), (raised, &server)].into_iter());
        }
        last_fault = fault;
    }
}
