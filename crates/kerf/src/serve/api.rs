//! The HTTP side: the web page, `GET /api/v1/status`, the status stream on
//! `GET /api/v1/ws` (WebSocket) and control on `POST /api/v1/control` (docs/API.md).
//!
//! Control needs the configured token (`Authorization: Bearer TOKEN`, compared by its
//! SHA-256 with `serve.control_token_sha256`) and a request from the page's own origin
//! (a browser's `Origin`, when sent, must name the host it asks); every refused control
//! request is logged on standard error with the client's address and the reason.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::mpsc::Sender;

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
        .route("/api/v1/program", post(program))
        .route("/api/v1/job", get(job))
        .route("/api/v1/job/toolpath", get(job_toolpath))
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
    let hash = super::hash_token(token.trim().as_bytes());
    // Compared without an early exit, so the time says nothing of where they differ.
    hash.iter()
        .zip(expected)
        .fold(0u8, |acc, (a, b)| acc | (a ^ b))
        == 0
}

/// Logs a refused request of `peer` and answers it.
fn refuse(peer: SocketAddr, status: StatusCode, code: &str, message: &str) -> Response {
    eprintln!("kerf serve: refused a control request from {peer}: {code}: {message}");
    error(status, code, message)
}

/// The checks every control request passes first: from the page's own origin, control
/// configured, the token presented. The refusal's answer, or None when it passes.
fn guard(app: &App, peer: SocketAddr, headers: &HeaderMap) -> Option<Response> {
    if cross_origin(headers) {
        return Some(refuse(
            peer,
            StatusCode::FORBIDDEN,
            "cross_origin",
            "a control request from another site's page is refused",
        ));
    }
    let Some(expected) = app.token_sha256 else {
        return Some(refuse(
            peer,
            StatusCode::FORBIDDEN,
            "control_disabled",
            "control through kerf serve is not configured (serve.control_token_sha256); watching needs no token",
        ));
    };
    if !authorized(headers, &expected) {
        return Some(refuse(
            peer,
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "control needs the token: `Authorization: Bearer TOKEN`",
        ));
    }
    None
}

async fn control(
    State(app): State<App>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    body: Body,
) -> Response {
    if let Some(refused) = guard(&app, peer, &headers) {
        return refused;
    }
    let refuse = |status, code, message: &str| refuse(peer, status, code, message);
    let bytes = match to_bytes(body, CONTROL_BODY_LIMIT).await {
        Ok(b) => b,
        Err(_) => {
            return refuse(
                StatusCode::PAYLOAD_TOO_LARGE,
                "too_large",
                &format!("a control request is at most {CONTROL_BODY_LIMIT} bytes"),
            );
        }
    };
    let request: ControlRequest = match serde_json::from_slice(&bytes) {
        Ok(r) => r,
        Err(e) => return refuse(StatusCode::BAD_REQUEST, "bad_request", &e.to_string()),
    };
    let command = match command(&app, request) {
        Ok(c) => c,
        Err(m) => return refuse(StatusCode::BAD_REQUEST, "bad_request", &m),
    };
    let (answer, answered) = oneshot::channel();
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
    if let Some(refused) = guard(&app, peer, &headers) {
        return refused;
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
    match app.jobs.start(&name, &text, start) {
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
        Err(StartRefused::Io(m)) => refuse(StatusCode::INTERNAL_SERVER_ERROR, "io", &m),
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
