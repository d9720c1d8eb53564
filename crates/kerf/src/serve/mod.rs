//! `kerf serve`: the machine's web page and JSON API beside `kerfd`, in a process of its
//! own that talks to the daemon only through its iceoryx2 services, as the CLI does
//! (docs/API.md).
//!
//! One thread is the [`link`] to the daemon (status at 20 Hz, control requests one at a
//! time); the HTTP server ([`api`], axum on tokio's single-threaded runtime) serves the
//! page, the status, its WebSocket stream and control. Nothing here touches the cycle.

pub mod api;
pub mod jobs;
pub mod lease;
pub mod link;
pub mod opcua;
pub mod page;
pub mod toolpath;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

use kerf_config::Config;
use sha2::{Digest, Sha256};
use tokio::sync::watch;

/// The API's version: the `api` field of every status message, the `v1` of the paths.
pub const API_VERSION: u32 = 1;

/// Why `kerf serve` could not run.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The address could not be listened on.
    #[error("cannot listen on {addr}: {source}")]
    Listen {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The runtime or the server failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// The SHA-256 of a control token (what `serve.control_token_sha256` holds).
pub fn hash_token(token: &[u8]) -> [u8; 32] {
    Sha256::digest(token).into()
}

/// `hash` as 64 lower-case hex digits.
pub fn hex(hash: &[u8; 32]) -> String {
    hash.iter().map(|b| format!("{b:02x}")).collect()
}

/// Serves the machine of `config` (read from `config_path`, or the default when None: the
/// file programs are run with): the page and the JSON API on `http`, OPC UA on `opcua`,
/// until SIGINT or SIGTERM. `ready` is called with the addresses listened on (their ports
/// when port 0 was asked for).
pub fn run(
    config: Config,
    config_path: Option<PathBuf>,
    http: SocketAddr,
    opcua: SocketAddr,
    ready: impl FnOnce(SocketAddr, SocketAddr),
) -> Result<(), ServeError> {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .build()?;
    let (status_tx, status_rx) = watch::channel(Arc::new(String::from(
        "{\"api\":1,\"seq\":0,\"t_ms\":0,\"connected\":false,\"reason\":\"starting\"}",
    )));
    let (asks_tx, asks_rx) = std::sync::mpsc::channel();
    // Programs are run by this very binary's `kerf run`.
    let kerf = std::env::current_exe()?;
    let jobs = jobs::Jobs::new(
        config.clone(),
        kerf,
        config_path,
        config.machine_program_directory(),
    );
    let opcua_status = status_rx.clone();
    let opcua_jobs = jobs.clone();
    let app = api::App {
        status: status_rx,
        asks: asks_tx,
        token_sha256: config.serve.control_token_sha256,
        axes: [
            true,
            true,
            true,
            config.axes.a.is_some(),
            config.axes.b.is_some(),
            config.axes.c.is_some(),
        ],
        jobs,
        lease: Arc::default(),
    };
    let link_config = config.clone();
    std::thread::Builder::new()
        .name("kerf-serve-link".into())
        .spawn(move || link::run(link_config, status_tx, asks_rx))?;
    runtime.block_on(async move {
        let listener = tokio::net::TcpListener::bind(http)
            .await
            .map_err(|source| ServeError::Listen { addr: http, source })?;
        let opcua_listener = tokio::net::TcpListener::bind(opcua)
            .await
            .map_err(|source| ServeError::Listen {
                addr: opcua,
                source,
            })?;
        let opcua_addr = opcua_listener.local_addr()?;
        let opcua_server = opcua::start(&config, opcua_listener, opcua_status, opcua_jobs)
            .await
            .map_err(|e| ServeError::Io(std::io::Error::other(format!("OPC UA: {e}"))))?;
        ready(listener.local_addr()?, opcua_addr);
        let service = api::router(app).into_make_service_with_connect_info::<SocketAddr>();
        axum::serve(listener, service)
            .with_graceful_shutdown(stopped())
            .await?;
        opcua_server.cancel();
        Ok(())
    })
}

/// Resolves at SIGINT or SIGTERM.
async fn stopped() {
    use tokio::signal::unix::{SignalKind, signal};
    let (Ok(mut term), Ok(mut int)) = (
        signal(SignalKind::terminate()),
        signal(SignalKind::interrupt()),
    ) else {
        // Without the handlers the process ends by the default action instead.
        return std::future::pending().await;
    };
    tokio::select! {
        _ = term.recv() => {}
        _ = int.recv() => {}
    }
}
