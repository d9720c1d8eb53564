//! Who may do what on the OPC UA server: the users' logins and roles, and the `Control`
//! object's methods (hold, resume, the overrides), which go to the daemon through the link
//! under the web API's control lease.

use super::*;
use crate::serve::link::{Answer, Refused};
use crate::serve::password_matches;

/// The OPC UA users: anonymous clients read everywhere; the configured users log in on
/// the secure endpoints only (never where a password would cross in clear), and only an
/// operator may call the control methods.
pub(super) struct Users {
    pub(super) users: Vec<OpcuaUser>,
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
        let matches = tokio::task::spawn_blocking(move || password_matches(&given, &kept))
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
    let answer: Answer = Box::new(move |a| {
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
pub(super) fn control_methods(
    config: &Config,
    manager: &SimpleNodeManager,
    ns: u16,
    feeds: &Feeds,
) {
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
