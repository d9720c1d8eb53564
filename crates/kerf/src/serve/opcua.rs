//! The OPC UA server of `kerf serve` (async-opcua): the machine as an object of the
//! Machines folder, laid out with the browse names of the OPC UA for Machine Tools
//! companion specification (OPC 40501-1) as far as Kerf has the data (docs/API.md, "OPC
//! UA"), its values taken from the same status the page shows, ten times a second.
//! Read-only: no variable is writable, so a client's write is refused by the server
//! (`BadNotWritable`); control stays with the JSON API and its token.

use std::net::SocketAddr;
use std::sync::Arc;

use kerf_config::Config;
use opcua::nodes::{AccessLevel, BaseEventType, ObjectBuilder, VariableBuilder};
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{SimpleNodeManager, simple_node_manager};
use opcua::server::{ServerBuilder, ServerHandle, SubscriptionCache};
use opcua::types::{
    ByteString, DataTypeId, DataValue, DateTime, LocalizedText, NodeId, ObjectId, ObjectTypeId,
    QualifiedName, UAString, Variant,
};
use serde_json::Value;
use tokio::sync::watch;

use super::jobs::{JobState, Jobs};

/// How often the values are refreshed.
pub const REFRESH: std::time::Duration = std::time::Duration::from_millis(100);

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
}

/// The axes' names as the status has them.
const AXES: [&str; 6] = ["x", "y", "z", "a", "b", "c"];

/// Machine tool operation mode (the Machinery specification's MachineryOperationMode):
/// 3 processing while a program runs or pauses, 2 setup while the machine moves by hand
/// or homes, 0 otherwise (none).
fn operation_mode(i: &Inputs) -> Variant {
    let state = i.status["state"].as_str().unwrap_or("");
    let mode: u32 = match state {
        "running" | "holding" | "paused" | "starved" | "stopping" => 3,
        "manual" => 2,
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

/// The active program's state (the ProductionProgramState names): "Running" while its
/// job runs and the machine moves it, "Interrupted" while held or paused, "Ended" when
/// it finished, "Aborted" when it failed, "Initializing" before the first.
fn program_state(i: &Inputs) -> Variant {
    let state = i.status["state"].as_str().unwrap_or("");
    let name = match i.job.map(|j| j.state) {
        None => "Initializing",
        Some(JobState::Finished) => "Ended",
        Some(JobState::Failed) => "Aborted",
        Some(JobState::Running) if matches!(state, "holding" | "paused" | "fault") => "Interrupted",
        Some(JobState::Running) => "Running",
    };
    Variant::from(UAString::from(name))
}

/// Starts the OPC UA server of `config`'s machine on `listener`, fed from `status` and
/// `jobs`; returns its handle (cancel it to stop the server).
pub async fn start(
    config: &Config,
    listener: tokio::net::TcpListener,
    status: watch::Receiver<Arc<String>>,
    jobs: Jobs,
) -> Result<ServerHandle, String> {
    let addr: SocketAddr = listener.local_addr().map_err(|e| e.to_string())?;
    let machine = config.machine.clone();
    let ns_uri = namespace_uri(&machine);
    let (server, handle) = ServerBuilder::new_anonymous(format!("Kerf {machine}"))
        .application_uri(application_uri(&machine))
        .product_uri("urn:kerf")
        .host(addr.ip().to_string())
        .port(addr.port())
        .pki_dir(std::env::temp_dir().join(format!("kerf-serve-pki-{machine}")))
        .create_sample_keypair(false)
        .with_node_manager(simple_node_manager(
            NamespaceMetadata {
                namespace_uri: ns_uri.clone(),
                ..Default::default()
            },
            "kerf",
        ))
        .build()?;
    let manager = handle
        .node_managers()
        .get_of_type::<SimpleNodeManager>()
        .ok_or("no node manager")?;
    let ns = handle
        .get_namespace_index(&ns_uri)
        .ok_or("no namespace index")?;
    let (machine_id, vars) = address_space(config, &manager, ns);
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
        status,
        jobs,
        handle.clone(),
    ));
    Ok(handle)
}

/// Builds the machine's nodes; the machine object's id and the variables to refresh.
fn address_space(config: &Config, manager: &SimpleNodeManager, ns: u16) -> (NodeId, Vec<Var>) {
    let machine = &config.machine;
    let id = |path: &str| NodeId::new(ns, format!("{machine}.{path}"));
    let name = |n: &str| QualifiedName::new(ns, n);
    let mut vars = Vec::new();
    let mut space = manager.address_space().write();
    let machines = NodeId::new(ns, "Machines");
    ObjectBuilder::new(&machines, name("Machines"), "Machines")
        .organized_by(ObjectId::ObjectsFolder)
        .has_type_definition(ObjectTypeId::FolderType)
        .insert(&mut *space);
    let root = NodeId::new(ns, machine.as_str());
    ObjectBuilder::new(&root, name(machine), machine.as_str())
        .organized_by(&machines)
        .has_type_definition(ObjectTypeId::BaseObjectType)
        .event_notifier(opcua::nodes::EventNotifier::SUBSCRIBE_TO_EVENTS)
        .insert(&mut *space);
    let object =
        |space: &mut opcua::server::address_space::AddressSpace, path: &str, parent: &NodeId| {
            let node = id(path);
            let leaf = path.rsplit('.').next().unwrap_or(path);
            ObjectBuilder::new(&node, name(leaf), leaf)
                .component_of(parent.clone())
                .has_type_definition(ObjectTypeId::BaseObjectType)
                .insert(space);
            node
        };
    let constant = |space: &mut opcua::server::address_space::AddressSpace,
                    path: &str,
                    parent: &NodeId,
                    value: &str| {
        let leaf = path.rsplit('.').next().unwrap_or(path);
        VariableBuilder::new(&id(path), name(leaf), leaf)
            .property_of(parent.clone())
            .data_type(DataTypeId::String)
            .value(UAString::from(value))
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .insert(space);
    };
    let mut variable = |space: &mut opcua::server::address_space::AddressSpace,
                        path: &str,
                        parent: &NodeId,
                        data_type: DataTypeId,
                        initial: Variant,
                        value: fn(&Inputs) -> Variant| {
        let leaf = path.rsplit('.').next().unwrap_or(path);
        let node = id(path);
        VariableBuilder::new(&node, name(leaf), leaf)
            .component_of(parent.clone())
            .data_type(data_type)
            .value(initial)
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .insert(space);
        vars.push(Var { id: node, value });
    };
    // Identification.
    let identification = object(&mut space, "Identification", &root);
    let s = &config.serve;
    constant(
        &mut space,
        "Identification.Manufacturer",
        &identification,
        &s.manufacturer,
    );
    constant(
        &mut space,
        "Identification.Model",
        &identification,
        &s.model,
    );
    let serial = if s.serial_number.is_empty() {
        machine.as_str()
    } else {
        s.serial_number.as_str()
    };
    constant(
        &mut space,
        "Identification.SerialNumber",
        &identification,
        serial,
    );
    constant(
        &mut space,
        "Identification.ProductInstanceUri",
        &identification,
        &format!("urn:kerf:{machine}"),
    );
    constant(
        &mut space,
        "Identification.SoftwareRevision",
        &identification,
        env!("CARGO_PKG_VERSION"),
    );
    // Monitoring.
    let monitoring = object(&mut space, "Monitoring", &root);
    let tool = object(&mut space, "Monitoring.MachineTool", &monitoring);
    variable(
        &mut space,
        "Monitoring.MachineTool.OperationMode",
        &tool,
        DataTypeId::UInt32,
        Variant::from(0u32),
        operation_mode,
    );
    variable(
        &mut space,
        "Monitoring.MachineTool.PowerOnDuration",
        &tool,
        DataTypeId::UInt32,
        Variant::from(0u32),
        |i| {
            // Hours the daemon has run: its cycles times its period.
            let cycles = i.status["cycles"].as_f64().unwrap_or(0.0);
            let period_us = i.status["period_us"].as_f64().unwrap_or(0.0);
            Variant::from((cycles * period_us / 3.6e9) as u32)
        },
    );
    let channel = object(&mut space, "Monitoring.Channel1", &monitoring);
    variable(
        &mut space,
        "Monitoring.Channel1.ChannelState",
        &channel,
        DataTypeId::Int32,
        Variant::from(2i32),
        channel_state,
    );
    variable(
        &mut space,
        "Monitoring.Channel1.FeedOverride",
        &channel,
        DataTypeId::Double,
        Variant::from(100.0),
        |i| Variant::from(i.status["override_pct"].as_f64().unwrap_or(0.0)),
    );
    let spindle = object(&mut space, "Monitoring.Spindle", &monitoring);
    variable(
        &mut space,
        "Monitoring.Spindle.Override",
        &spindle,
        DataTypeId::Double,
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
        &spindle,
        DataTypeId::Boolean,
        Variant::from(false),
        |i| {
            Variant::from(
                i.status["spindle"]["actual_rpm"]
                    .as_f64()
                    .is_some_and(|r| r.abs() > 0.5),
            )
        },
    );
    let present = [
        true,
        true,
        true,
        config.axes.a.is_some(),
        config.axes.b.is_some(),
        config.axes.c.is_some(),
    ];
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
        let node = object(&mut space, &format!("Monitoring.{upper}"), &monitoring);
        variable(
            &mut space,
            &format!("Monitoring.{upper}.ActualPosition"),
            &node,
            DataTypeId::Double,
            Variant::from(0.0),
            position[k],
        );
    }
    // Production.
    let production = object(&mut space, "Production", &root);
    let program = object(&mut space, "Production.ActiveProgram", &production);
    variable(
        &mut space,
        "Production.ActiveProgram.Name",
        &program,
        DataTypeId::String,
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
        "Production.ActiveProgram.State",
        &program,
        DataTypeId::String,
        Variant::from(UAString::from("Initializing")),
        program_state,
    );
    variable(
        &mut space,
        "Production.ActiveProgram.Line",
        &program,
        DataTypeId::UInt32,
        Variant::from(0u32),
        |i| Variant::from(i.status["line"].as_u64().unwrap_or(0) as u32),
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
