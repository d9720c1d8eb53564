//! The HTTP side: the web page, `GET /api/v1/status`, the status stream on
//! `GET /api/v1/ws` (WebSocket) and control on `POST /api/v1/control` (docs/API.md).
//!
//! Control needs the configured token (`Authorization: Bearer TOKEN`, compared by its
//! SHA-256 with `serve.control_token_sha256`) and a request from the page's own origin
//! (a browser's `Origin`, when sent, must name the host it asks), and, while another
//! client holds the control lease, only stops (the [`super::lease`]); every refused
//! control request is logged on standard error with the client's address and the reason.

use std::net::SocketAddr;
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use axum::Router;
use axum::body::{Body, to_bytes};
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use kerf_proto::{ControlCommand, Jog, Switch};
use serde::Deserialize;
use tokio::sync::{oneshot, watch};

use super::jobs::{Jobs, PROGRAM_LIMIT, StartRefused, job_json, valid_name};
use super::lease::{Holder, LEASE_TTL, Lease, valid_client};
use super::link::{Ask, Refused, STATUS_PERIOD, json_string};
use super::page;

/// The largest control request body, bytes.
pub const CONTROL_BODY_LIMIT: usize = 16 * 1024;

/// What every handler shares.
#[derive(Clone)]
pub struct App {
    /// The latest status message.
    pub status: watch::Receiver<Arc<String>>,
    /// Control requests to the link.
    pub asks: Sender<Ask>,
    /// `serve.control_token_sha256`.
    pub token_sha256: Option<[u8; 32]>,
    /// The axes the machine has, X to C.
    pub axes: [bool; 6],
    /// Programs run from the page or the API.
    pub jobs: Jobs,
    /// Who controls the machine.
    pub lease: Arc<Mutex<Lease>>,
}

/// The router of the page and the API.
pub fn router(app: App) -> Router {
    Router::new()
        .route("/", get(|| async { page::html() }))
        .route("/app.js", get(|| async { page::script() }))
        .route("/style.css", get(|| async { page::style() }))
        .route("/api/v1/status", get(status))
        .route("/api/v1/ws", get(ws))
        .route("/api/v1/control", post(control))
        .route("/api/v1/control/lease", get(lease).post(take_lease))
        .route("/api/v1/program", post(program))
        .route("/api/v1/mdi", post(mdi))
        .route("/api/v1/job", get(job))
        .route("/api/v1/job/toolpath", get(job_toolpath))
        .route("/api/v1/fault/blackbox.svg", get(blackbox))
        .fallback(|| async { error(StatusCode::NOT_FOUND, "not_found", "no such page or API") })
        .with_state(app)
}

/// An error as the API answers it: `{"error":{"code":…,"message":…}}`.
pub fn error(status: StatusCode, code: &str, message: &str) -> Response {
    json(
        status,
        format!(
            "{{\"error\":{{\"code\":{},\"message\":{}}}}}",
            json_string(code),
            json_string(message)
        ),
    )
}

fn json(status: StatusCode, body: String) -> Response {
    (
        status,
        [
            (header::CONTENT_TYPE, "application/json"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body,
    )
        .into_response()
}

async fn status(State(app): State<App>) -> Response {
    let latest = app.status.borrow().clone();
    json(StatusCode::OK, latest.as_str().to_owned())
}

async fn ws(ws: WebSocketUpgrade, State(app): State<App>) -> Response {
    ws.on_upgrade(move |socket| stream_status(socket, app.status.clone()))
}

/// Sends the latest status at most every [`STATUS_PERIOD`] (20 Hz), skipping what a slow
/// client had no time for; ends when the client closes or goes away.
async fn stream_status(mut socket: WebSocket, mut status: watch::Receiver<Arc<String>>) {
    let mut tick = tokio::time::interval(STATUS_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    status.mark_changed();
    loop {
        tokio::select! {
            _ = tick.tick() => {
                if !status.has_changed().unwrap_or(false) {
                    continue;
                }
                let latest = status.borrow_and_update().clone();
                if socket.send(Message::Text(latest.as_str().into())).await.is_err() {
                    return;
                }
            }
            incoming = socket.recv() => match incoming {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return,
                Some(Ok(_)) => {}
            },
        }
    }
}

/// A control request's body (`{"command":"hold"}`, `{"command":"override","percent":50}`,
/// ...); see docs/API.md.
#[derive(Debug, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case", deny_unknown_fields)]
enum ControlRequest {
    Hold,
    Resume,
    Abort,
    Reset,
    Override {
        percent: f64,
    },
    SpindleOverride {
        percent: f64,
    },
    Home {
        axes: String,
    },
    Jog {
        axis: String,
        direction: String,
        speed: Option<f64>,
    },
    JogStep {
        axis: String,
        distance: f64,
        speed: Option<f64>,
    },
    JogTo {
        axis: String,
        position: f64,
        speed: Option<f64>,
    },
    JogStop {
        axis: String,
    },
    Switch {
        name: String,
        on: bool,
    },
}

/// Axis `name` (X to C, either case) of the machine, 0 to 5.
fn axis(app: &App, name: &str) -> Result<u8, String> {
    let index = match name.to_ascii_uppercase().as_str() {
        "X" => 0,
        "Y" => 1,
        "Z" => 2,
        "A" => 3,
        "B" => 4,
        "C" => 5,
        _ => return Err(format!("unknown axis `{name}`: X, Y, Z, A, B or C")),
    };
    if !app.axes[index] {
        return Err(format!(
            "the machine has no axis {}",
            name.to_ascii_uppercase()
        ));
    }
    Ok(index as u8)
}

/// The daemon's command for `request`, or why it is malformed.
fn command(app: &App, request: ControlRequest) -> Result<ControlCommand, String> {
    let speed = |s: Option<f64>| s.unwrap_or(0.0);
    Ok(match request {
        ControlRequest::Hold => ControlCommand::Hold,
        ControlRequest::Resume => ControlCommand::Resume,
        ControlRequest::Abort => ControlCommand::Abort,
        ControlRequest::Reset => ControlCommand::Reset,
        ControlRequest::Override { percent } => ControlCommand::Override { percent },
        ControlRequest::SpindleOverride { percent } => ControlCommand::SpindleOverride { percent },
        ControlRequest::Home { axes } => {
            let mut mask = 0u32;
            if axes.eq_ignore_ascii_case("all") {
                for (i, on) in app.axes.iter().enumerate() {
                    if *on {
                        mask |= 1 << i;
                    }
                }
            } else {
                for c in axes.chars() {
                    mask |= 1 << axis(app, &c.to_string())?;
                }
            }
            if mask == 0 {
                return Err("`axes` names no axis: \"all\" or letters such as \"XY\"".into());
            }
            ControlCommand::Home { axes: mask }
        }
        ControlRequest::Jog {
            axis: a,
            direction,
            speed: s,
        } => {
            let positive = match direction.as_str() {
                "+" => true,
                "-" => false,
                _ => {
                    return Err(format!(
                        "`direction` must be \"+\" or \"-\", found `{direction}`"
                    ));
                }
            };
            ControlCommand::Jog {
                axis: axis(app, &a)?,
                jog: Jog::Continuous(positive),
                speed: speed(s),
            }
        }
        ControlRequest::JogStep {
            axis: a,
            distance,
            speed: s,
        } => ControlCommand::Jog {
            axis: axis(app, &a)?,
            jog: Jog::Step(distance),
            speed: speed(s),
        },
        ControlRequest::JogTo {
            axis: a,
            position,
            speed: s,
        } => ControlCommand::Jog {
            axis: axis(app, &a)?,
            jog: Jog::To(position),
            speed: speed(s),
        },
        ControlRequest::JogStop { axis: a } => ControlCommand::JogStop {
            axis: axis(app, &a)?,
        },
        ControlRequest::Switch { name, on } => {
            let switch = match name.as_str() {
                "optional_stop" => Switch::OptionalStop,
                "single_block" => Switch::SingleBlock,
                "block_delete" => Switch::BlockDelete,
                _ => {
                    return Err(format!(
                        "unknown switch `{name}`: optional_stop, single_block or block_delete"
                    ));
                }
            };
            ControlCommand::Switch { switch, on }
        }
    })
}

/// Whether the request comes from another origin than the host it asks: a browser sends
/// `Origin` on a POST; a page of another site may not control the machine. A client that
/// sends no `Origin` (not a browser) is not cross-origin.
fn cross_origin(headers: &HeaderMap) -> bool {
    if headers
        .get("sec-fetch-site")
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v == "cross-site")
    {
        return true;
    }
    let Some(origin) = headers.get(header::ORIGIN) else {
        return false;
    };
    let host = headers.get(header::HOST).and_then(|h| h.to_str().ok());
    let origin_host = origin
        .to_str()
        .ok()
        .and_then(|o| o.split_once("://"))
        .map(|(_, rest)| rest.trim_end_matches('/'));
    match (origin_host, host) {
        (Some(o), Some(h)) => !o.eq_ignore_ascii_case(h),
        _ => true,
    }
}

/// Whether `headers` carry the control token whose SHA-256 is `expected`.
fn authorized(headers: &HeaderMap, expected: &[u8; 32]) -> bool {
    let Some(token) = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
    else {
        return false;
    };
    super::same_hash(&super::hash_token(token.trim().as_bytes()), expected)
}

/// Logs a refused request of `peer` and answers it.
fn refuse(peer: SocketAddr, status: StatusCode, code: &str, message: &str) -> Response {
    eprintln!("kerf serve: refused a control request from {peer}: {code}: {message}");
    error(status, code, message)
}

/// A refusal's answer, boxed (an `Err` as small as an `Ok`).
type Refusal = Box<Response>;

/// The checks every control request passes first: from the page's own origin, control
/// configured, the token presented, a well-formed `Kerf-Client` id if any. The client's
/// id (None without the header), or the refusal's answer.
fn guard(app: &App, peer: SocketAddr, headers: &HeaderMap) -> Result<Option<String>, Refusal> {
    if cross_origin(headers) {
        return Err(Box::new(refuse(
            peer,
            StatusCode::FORBIDDEN,
            "cross_origin",
            "a control request from another site's page is refused",
        )));
    }
    let Some(expected) = app.token_sha256 else {
        return Err(Box::new(refuse(
            peer,
            StatusCode::FORBIDDEN,
            "control_disabled",
            "control through kerf serve is not configured (serve.control_token_sha256); watching needs no token",
        )));
    };
    if !authorized(headers, &expected) {
        return Err(Box::new(refuse(
            peer,
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "control needs the token: `Authorization: Bearer TOKEN`",
        )));
    }
    match headers.get(CLIENT_HEADER).map(|v| v.to_str()) {
        None => Ok(None),
        Some(Ok(id)) if valid_client(id) => Ok(Some(id.to_owned())),
        Some(_) => Err(Box::new(refuse(
            peer,
            StatusCode::BAD_REQUEST,
            "bad_request",
            "`Kerf-Client` must be 8 to 64 of A-Z, a-z, 0-9 and `-`",
        ))),
    }
}

/// The header a client names itself with for the control lease.
pub const CLIENT_HEADER: &str = "kerf-client";

/// Where the lease's holder is, for a refusal.
fn held_elsewhere(holder: &Holder, now: Instant) -> String {
    format!(
        "the machine is controlled from {} (for {:.0} s): stopping is allowed, anything else needs control (take it over with {{\"action\":\"take\",\"force\":true}} on /api/v1/control/lease)",
        holder.peer,
        now.saturating_duration_since(holder.since).as_secs_f64()
    )
}

/// Whether `client` may go on under the lease (`stops`: the request only stops motion);
/// the refusal's answer otherwise.
fn leased(app: &App, peer: SocketAddr, client: Option<&str>, stops: bool) -> Result<(), Refusal> {
    let now = Instant::now();
    let Ok(mut lease) = app.lease.lock() else {
        return Err(Box::new(refuse(
            peer,
            StatusCode::INTERNAL_SERVER_ERROR,
            "io",
            "the control lease is poisoned",
        )));
    };
    lease.permits(client, stops, now).map_err(|holder| {
        Box::new(refuse(
            peer,
            StatusCode::CONFLICT,
            "controlled_elsewhere",
            &held_elsewhere(&holder, now),
        ))
    })
}

/// A JSON request body of at most [`CONTROL_BODY_LIMIT`] bytes (`what` it is, for the
/// refusal), parsed.
async fn json_body<T: serde::de::DeserializeOwned>(
    peer: SocketAddr,
    body: Body,
    what: &str,
) -> Result<T, Refusal> {
    let Ok(bytes) = to_bytes(body, CONTROL_BODY_LIMIT).await else {
        return Err(Box::new(refuse(
            peer,
            StatusCode::PAYLOAD_TOO_LARGE,
            "too_large",
            &format!("{what} is at most {CONTROL_BODY_LIMIT} bytes"),
        )));
    };
    serde_json::from_slice(&bytes).map_err(|e| {
        Box::new(refuse(
            peer,
            StatusCode::BAD_REQUEST,
            "bad_request",
            &e.to_string(),
        ))
    })
}

async fn control(
    State(app): State<App>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    let client = match guard(&app, peer, &headers) {
        Ok(c) => c,
        Err(refused) => return *refused,
    };
    let refuse = |status, code, message: &str| refuse(peer, status, code, message);
    let request: ControlRequest = match json_body(peer, body, "a control request").await {
        Ok(r) => r,
        Err(refused) => return *refused,
    };
    let command = match command(&app, request) {
        Ok(c) => c,
        Err(m) => return refuse(StatusCode::BAD_REQUEST, "bad_request", &m),
    };
    let stops = matches!(
        command,
        ControlCommand::Hold | ControlCommand::Abort | ControlCommand::JogStop { .. }
    );
    if let Err(refused) = leased(&app, peer, client.as_deref(), stops) {
        return *refused;
    }
    let (answer, answered) = oneshot::channel();
    let answer: super::link::Answer = Box::new(move |a| {
        let _ = answer.send(a);
    });
    if app.asks.send(Ask { command, answer }).is_err() {
        return refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            "no_daemon",
            "the link to the daemon stopped",
        );
    }
    match answered.await {
        Ok(Ok(status)) => json(
            StatusCode::OK,
            format!("{{\"ok\":true,\"status\":{status}}}"),
        ),
        Ok(Err(Refused::Daemon(m))) => refuse(StatusCode::CONFLICT, "refused", &m),
        Ok(Err(Refused::NoDaemon(m))) => refuse(StatusCode::SERVICE_UNAVAILABLE, "no_daemon", &m),
        Err(_) => refuse(
            StatusCode::SERVICE_UNAVAILABLE,
            "no_daemon",
            "the link to the daemon stopped",
        ),
    }
}

/// The query of `POST /api/v1/program`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProgramQuery {
    name: String,
}

/// `POST /api/v1/program?name=NAME`: the body is the program's text; it is kept and run by
/// `kerf run` (a job).
async fn program(
    State(app): State<App>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    query: Result<axum::extract::Query<ProgramQuery>, axum::extract::rejection::QueryRejection>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    let client = match guard(&app, peer, &headers) {
        Ok(c) => c,
        Err(refused) => return *refused,
    };
    if let Err(refused) = leased(&app, peer, client.as_deref(), false) {
        return *refused;
    }
    let refuse = |status, code, message: &str| refuse(peer, status, code, message);
    let name = match query {
        Ok(q) if valid_name(&q.name) => q.0.name,
        Ok(q) => {
            return refuse(
                StatusCode::BAD_REQUEST,
                "bad_request",
                &format!(
                    "`name` must be a plain file name (1 to 100 of A-Z, a-z, 0-9, `.`, `_`, `-`, not starting with `.`), found `{}`",
                    q.name
                ),
            );
        }
        Err(e) => return refuse(StatusCode::BAD_REQUEST, "bad_request", &e.body_text()),
    };
    let text = match to_bytes(body, PROGRAM_LIMIT).await {
        Ok(b) => b,
        Err(_) => {
            return refuse(
                StatusCode::PAYLOAD_TOO_LARGE,
                "too_large",
                &format!("a program is at most {PROGRAM_LIMIT} bytes; nothing runs"),
            );
        }
    };
    // The toolpath starts where the machine stands now.
    let start = {
        let latest = app.status.borrow().clone();
        let m: serde_json::Value = serde_json::from_str(&latest).unwrap_or_default();
        let axis = |a: &str| m["status"]["position"][a].as_f64().unwrap_or(0.0);
        [axis("x"), axis("y"), axis("z")]
    };
    started(&app, peer, app.jobs.start(&name, &text, start))
}

/// The answer to a job started (or not).
fn started(app: &App, peer: SocketAddr, result: Result<u64, StartRefused>) -> Response {
    let refuse = |status, code, message: &str| refuse(peer, status, code, message);
    match result {
        Ok(_) => json(
            StatusCode::ACCEPTED,
            format!(
                "{{\"ok\":true,\"job\":{}}}",
                job_json(app.jobs.current().as_ref())
            ),
        ),
        Err(StartRefused::Busy(id)) => refuse(
            StatusCode::CONFLICT,
            "busy",
            &format!("job {id} still runs: hold or abort it, or wait for its end"),
        ),
        Err(StartRefused::Name(n)) => refuse(
            StatusCode::BAD_REQUEST,
            "bad_request",
            &format!("bad name `{n}`"),
        ),
        Err(StartRefused::Line(m)) => refuse(StatusCode::BAD_REQUEST, "bad_request", &m),
        Err(StartRefused::Io(m)) => refuse(StatusCode::INTERNAL_SERVER_ERROR, "io", &m),
    }
}

/// The body of `POST /api/v1/mdi`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MdiRequest {
    line: String,
}

/// `POST /api/v1/mdi` with `{"line":"G0 X10"}`: the line is run by `kerf mdi LINE` (a job).
async fn mdi(
    State(app): State<App>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    let client = match guard(&app, peer, &headers) {
        Ok(c) => c,
        Err(refused) => return *refused,
    };
    let request: MdiRequest = match json_body(peer, body, "an MDI request").await {
        Ok(r) => r,
        Err(refused) => return *refused,
    };
    if let Err(refused) = leased(&app, peer, client.as_deref(), false) {
        return *refused;
    }
    started(&app, peer, app.jobs.start_mdi(&request.line))
}

/// The lease as the API's JSON (`null` when nobody holds it); `yours` when `client` holds
/// it.
fn lease_json(app: &App, client: Option<&str>) -> String {
    let now = Instant::now();
    let Ok(lease) = app.lease.lock() else {
        return "null".into();
    };
    match lease.holder(now) {
        None => "null".into(),
        Some(h) => format!(
            "{{\"peer\":{},\"held_s\":{:.1},\"expires_in_s\":{:.1},\"yours\":{}}}",
            json_string(&h.peer.to_string()),
            now.saturating_duration_since(h.since).as_secs_f64(),
            LEASE_TTL
                .saturating_sub(now.saturating_duration_since(h.renewed))
                .as_secs_f64(),
            client == Some(h.client.as_str())
        ),
    }
}

/// `GET /api/v1/control/lease`: who controls the machine.
async fn lease(State(app): State<App>, headers: HeaderMap) -> Response {
    let client = headers
        .get(CLIENT_HEADER)
        .and_then(|v| v.to_str().ok())
        .filter(|id| valid_client(id));
    json(
        StatusCode::OK,
        format!("{{\"lease\":{}}}", lease_json(&app, client)),
    )
}

/// The body of `POST /api/v1/control/lease`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LeaseRequest {
    action: LeaseAction,
    #[serde(default)]
    force: bool,
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "snake_case")]
enum LeaseAction {
    Take,
    Release,
}

/// `POST /api/v1/control/lease`: `{"action":"take"}` (also renews; `"force":true` takes it
/// from another holder) or `{"action":"release"}`, with the client's `Kerf-Client` id.
async fn take_lease(
    State(app): State<App>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    let client = match guard(&app, peer, &headers) {
        Ok(Some(c)) => c,
        Ok(None) => {
            return refuse(
                peer,
                StatusCode::BAD_REQUEST,
                "bad_request",
                "the control lease needs the client's id in `Kerf-Client`",
            );
        }
        Err(refused) => return *refused,
    };
    let request: LeaseRequest = match json_body(peer, body, "a lease request").await {
        Ok(r) => r,
        Err(refused) => return *refused,
    };
    let now = Instant::now();
    let outcome = match app.lease.lock() {
        Err(_) => Err("the control lease is poisoned".to_owned()),
        Ok(mut lease) => match request.action {
            LeaseAction::Release => {
                lease.release(&client, now);
                Ok(())
            }
            LeaseAction::Take => {
                let before = lease.holder(now).cloned();
                match lease.take(&client, peer, request.force, now) {
                    Ok(()) => {
                        if let Some(b) = before.filter(|b| b.client != client) {
                            eprintln!("kerf serve: control taken over by {peer} from {}", b.peer);
                        }
                        Ok(())
                    }
                    Err(holder) => Err(held_elsewhere(&holder, now)),
                }
            }
        },
    };
    match outcome {
        Ok(()) => json(
            StatusCode::OK,
            format!(
                "{{\"ok\":true,\"lease\":{}}}",
                lease_json(&app, Some(&client))
            ),
        ),
        Err(m) => refuse(peer, StatusCode::CONFLICT, "controlled_elsewhere", &m),
    }
}

/// `GET /api/v1/fault/blackbox.svg`: the black box the daemon wrote at its fault (the
/// status's `safety.dump`), drawn as `kerf plot` draws it; 404 when there is none.
async fn blackbox(State(app): State<App>) -> Response {
    let latest = app.status.borrow().clone();
    let m: serde_json::Value = serde_json::from_str(&latest).unwrap_or_default();
    let Some(path) = m["status"]["safety"]["dump"].as_str().map(str::to_owned) else {
        return error(
            StatusCode::NOT_FOUND,
            "not_found",
            "no black box: the daemon has written none since its last reset",
        );
    };
    let drawn = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, String> {
        let file = std::fs::File::open(&path).map_err(|e| format!("{path}: {e}"))?;
        let bb = crate::blackbox::read(std::io::BufReader::new(file))
            .map_err(|e| format!("{path}: {e}"))?;
        let mut svg = Vec::new();
        crate::blackbox::write_svg(&bb, &mut svg).map_err(|e| e.to_string())?;
        Ok(svg)
    })
    .await;
    match drawn {
        Ok(Ok(svg)) => (
            StatusCode::OK,
            [
                (header::CONTENT_TYPE, "image/svg+xml"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            svg,
        )
            .into_response(),
        Ok(Err(m)) => error(StatusCode::INTERNAL_SERVER_ERROR, "io", &m),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, "io", &e.to_string()),
    }
}

/// `GET /api/v1/job`: the current or last job, `null` before the first.
async fn job(State(app): State<App>) -> Response {
    json(
        StatusCode::OK,
        format!("{{\"job\":{}}}", job_json(app.jobs.current().as_ref())),
    )
}

/// `GET /api/v1/job/toolpath`: the current or last job's toolpath (404 before the first,
/// or while it is still being computed).
async fn job_toolpath(State(app): State<App>) -> Response {
    match app.jobs.current().and_then(|j| j.toolpath) {
        Some(t) => json(StatusCode::OK, t.as_str().to_owned()),
        None => error(
            StatusCode::NOT_FOUND,
            "not_found",
            "no job, or its toolpath is not computed yet",
        ),
    }
}
