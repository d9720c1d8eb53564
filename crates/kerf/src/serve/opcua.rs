//! The OPC UA server of `kerf serve` (async-opcua): the machine as an object of the
//! Machines folder, laid out with the browse names of the OPC UA for Machine Tools
//! companion specification (OPC 40501-1) as far as Kerf has the data (docs/API.md, "OPC
//! UA"), its values taken from the same status the page shows, ten times a second.
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
use opcua::server::authenticator::{AuthManager, Password, UserToken};
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{SimpleNodeManager, simple_node_manager};
use opcua::server::{
    ANONYMOUS_USER_TOKEN_ID, ServerBuilder, ServerEndpoint, ServerHandle, SubscriptionCache,
};
use opcua::types::{
    Argument, ByteString, DataTypeId, DataValue, DateTime, Error as UaError, LocalizedText, NodeId,
    ObjectId, ObjectTypeId, QualifiedName, StatusCode, UAString, UserTokenPolicy, UserTokenType,
    Variant,
};
use serde_json::Value;
use tokio::sync::watch;

use super::jobs::{JobState, Jobs};
use super::lease::Lease;
use super::link::{Ask, Refused};

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
    control_methods(config, &manager, ns, &feeds);
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
    ));
    Ok(handle)
}

/// The OPC UA users: anonymous clients read everywhere; the configured users log in on
/// the secure endpoints only (never where a password would cross in clear), and only an
/// operator may call the control methods.
struct Users {
    users: Vec<OpcuaUser>,
}

impl Users {
    fn role(&self, token: &UserToken) -> Option<OpcuaRole> {
        self.users
            .iter()
            .find(|u| !token.is_anonymous() && u.name == token.0)
            .map(|u| u.role)
    }
}

#[async_trait::async_trait]
impl AuthManager for Users {
    async fn authenticate_anonymous_token(
        &self,
        _endpoint: &ServerEndpoint,
    ) -> Result<(), UaError> {
        Ok(())
    }

    async fn authenticate_username_identity_token(
        &self,
        endpoint: &ServerEndpoint,
        username: &str,
        password: &Password,
    ) -> Result<UserToken, UaError> {
        let refused = |why: &str| {
            eprintln!("kerf serve: refused the OPC UA login of `{username}`: {why}");
            Err(UaError::new(
                StatusCode::BadUserAccessDenied,
                format!("cannot log in `{username}`"),
            ))
        };
        if endpoint.security_policy() == SecurityPolicy::None {
            return refused("not on an endpoint without security");
        }
        let Some(user) = self.users.iter().find(|u| u.name == username).cloned() else {
            return refused("no such user");
        };
        // PBKDF2 takes a while on purpose: off the runtime's thread.
        let given = password.get().to_owned();
        let kept = user.password.clone();
        let matches = tokio::task::spawn_blocking(move || super::password_matches(&given, &kept))
            .await
            .unwrap_or(false);
        if !matches {
            return refused("wrong password");
        }
        Ok(UserToken(user.name))
    }

    fn is_user_executable(&self, token: &UserToken, _method_id: &NodeId) -> bool {
        self.role(token) == Some(OpcuaRole::Operator)
    }

    fn user_token_policies(&self, endpoint: &ServerEndpoint) -> Vec<UserTokenPolicy> {
        let mut policies = vec![UserTokenPolicy {
            policy_id: UAString::from("anonymous"),
            token_type: UserTokenType::Anonymous,
            issued_token_type: UAString::null(),
            issuer_endpoint_url: UAString::null(),
            security_policy_uri: UAString::null(),
        }];
        if !self.users.is_empty() && endpoint.security_policy() != SecurityPolicy::None {
            policies.push(UserTokenPolicy {
                policy_id: opcua::server::authenticator::user_pass_security_policy_id(endpoint),
                token_type: UserTokenType::UserName,
                issued_token_type: UAString::null(),
                issuer_endpoint_url: UAString::null(),
                security_policy_uri: UAString::null(),
            });
        }
        policies
    }
}

/// How long a control method waits for the daemon's answer.
const CALL_PATIENCE: Duration = Duration::from_secs(5);

/// Asks the daemon for `command` on behalf of an OPC UA operator (`method`, for the log):
/// under the control lease (hold is a stop, always allowed), answered within
/// [`CALL_PATIENCE`]. A refusal is logged and is `BadInvalidState`; no daemon is
/// `BadNoCommunication`.
fn call(
    asks: &Sender<Ask>,
    lease: &Mutex<Lease>,
    method: &str,
    command: ControlCommand,
) -> Result<Vec<Variant>, StatusCode> {
    let stops = matches!(command, ControlCommand::Hold);
    let refuse = |why: String, code: StatusCode| {
        eprintln!("kerf serve: refused the OPC UA call {method}: {why}");
        Err(code)
    };
    let held = lease
        .lock()
        .map_err(|_| StatusCode::BadInternalError)?
        .permits(None, stops, Instant::now());
    if let Err(holder) = held {
        return refuse(
            format!("the machine is controlled from {}", holder.peer),
            StatusCode::BadInvalidState,
        );
    }
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    let answer: super::link::Answer = Box::new(move |a| {
        let _ = tx.send(a);
    });
    if asks.send(Ask { command, answer }).is_err() {
        return refuse(
            "the link to the daemon stopped".into(),
            StatusCode::BadNoCommunication,
        );
    }
    // The link answers within its own request timeout; this thread waits that long at
    // most (a few milliseconds when the daemon answers).
    match rx.recv_timeout(CALL_PATIENCE) {
        Ok(Ok(_)) => Ok(Vec::new()),
        Ok(Err(Refused::Daemon(m))) => refuse(m, StatusCode::BadInvalidState),
        Ok(Err(Refused::NoDaemon(m))) => refuse(m, StatusCode::BadNoCommunication),
        Err(_) => refuse(
            "the daemon did not answer".into(),
            StatusCode::BadNoCommunication,
        ),
    }
}

/// The percent of a SetFeedOverride or SetSpindleOverride call: one Double, 0 to 200.
fn percent(args: &[Variant]) -> Result<f64, StatusCode> {
    match args {
        [Variant::Double(p)] if (0.0..=200.0).contains(p) => Ok(*p),
        [Variant::Double(_)] => Err(StatusCode::BadOutOfRange),
        _ => Err(StatusCode::BadInvalidArgument),
    }
}

/// The daemon's command of a control method's call, from its arguments.
type MethodCommand = fn(&[Variant]) -> Result<ControlCommand, StatusCode>;

/// The machine's `Control` object and its methods: Hold, Resume, SetFeedOverride and
/// SetSpindleOverride (executable by an operator only).
fn control_methods(config: &Config, manager: &SimpleNodeManager, ns: u16, feeds: &Feeds) {
    let machine = &config.machine;
    let id = |path: &str| NodeId::new(ns, format!("{machine}.{path}"));
    let name = |n: &str| QualifiedName::new(ns, n);
    let root = NodeId::new(ns, machine.as_str());
    let control = id("Control");
    {
        let mut space = manager.address_space().write();
        ObjectBuilder::new(&control, name("Control"), "Control")
            .component_of(root)
            .has_type_definition(ObjectTypeId::BaseObjectType)
            .insert(&mut *space);
        for (method, percent_of) in [
            ("Hold", None),
            ("Resume", None),
            ("SetFeedOverride", Some("the feed override, 0 to 200 %")),
            (
                "SetSpindleOverride",
                Some("the spindle override, 0 to 200 %"),
            ),
        ] {
            let node = id(&format!("Control.{method}"));
            let mut b = MethodBuilder::new(&node, name(method), method)
                .component_of(control.clone())
                .executable(true)
                .user_executable(true);
            if let Some(what) = percent_of {
                b = b.input_args(
                    &mut *space,
                    &id(&format!("Control.{method}.InputArguments")),
                    &[Argument {
                        name: UAString::from("Percent"),
                        data_type: DataTypeId::Double.into(),
                        value_rank: -1,
                        array_dimensions: None,
                        description: LocalizedText::from(what),
                    }],
                );
            }
            b.insert(&mut *space);
        }
    }
    let callbacks: [(&str, MethodCommand); 4] = [
        ("Hold", |_| Ok(ControlCommand::Hold)),
        ("Resume", |_| Ok(ControlCommand::Resume)),
        ("SetFeedOverride", |a| {
            percent(a).map(|percent| ControlCommand::Override { percent })
        }),
        ("SetSpindleOverride", |a| {
            percent(a).map(|percent| ControlCommand::SpindleOverride { percent })
        }),
    ];
    for (method, command) in callbacks {
        let (asks, lease) = (feeds.asks.clone(), Arc::clone(&feeds.lease));
        manager
            .inner()
            .add_method_callback(id(&format!("Control.{method}")), move |args| {
                call(&asks, &lease, method, command(args)?)
            });
    }
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
