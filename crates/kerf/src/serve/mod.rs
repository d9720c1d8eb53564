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

/// How long `kerf serve` waits, as it stops, for a running job to stop.
pub const JOB_STOP_PATIENCE: std::time::Duration = std::time::Duration::from_secs(10);

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

/// PBKDF2 iterations of a new password hash (OWASP's recommendation for
/// PBKDF2-HMAC-SHA256).
pub const PASSWORD_ITERATIONS: u32 = 600_000;

/// The PBKDF2-HMAC-SHA256 of `password` with `salt` over `iterations`.
pub fn derive_password(password: &[u8], salt: &[u8], iterations: u32) -> [u8; 32] {
    let mut key = [0u8; 32];
    pbkdf2::pbkdf2_hmac::<Sha256>(password, salt, iterations, &mut key);
    key
}

/// A new hash of `password` for `serve.opcua_users`, with 16 random bytes of salt (from
/// the kernel's random source).
pub fn hash_password(password: &str) -> std::io::Result<kerf_config::PasswordHash> {
    use std::io::Read;
    let mut salt = vec![0u8; 16];
    std::fs::File::open("/dev/urandom")?.read_exact(&mut salt)?;
    let hash = derive_password(password.as_bytes(), &salt, PASSWORD_ITERATIONS);
    Ok(kerf_config::PasswordHash {
        iterations: PASSWORD_ITERATIONS,
        salt,
        hash,
    })
}

/// Whether `password` is the one `kept` was made from; compared without an early exit.
pub fn password_matches(password: &str, kept: &kerf_config::PasswordHash) -> bool {
    let derived = derive_password(password.as_bytes(), &kept.salt, kept.iterations);
    same_hash(&derived, &kept.hash)
}

/// Whether two hashes are equal, compared without an early exit, so that the time says
/// nothing of where they differ.
pub fn same_hash(a: &[u8; 32], b: &[u8; 32]) -> bool {
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// `hash` as 64 lower-case hex digits.
pub fn hex(hash: &[u8; 32]) -> String {
    kerf_config::to_hex(hash)
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
    let lease = Arc::new(std::sync::Mutex::new(lease::Lease::default()));
    let feeds = opcua::Feeds {
        status: status_rx.clone(),
        jobs: jobs.clone(),
        asks: asks_tx.clone(),
        lease: Arc::clone(&lease),
    };
    let jobs_at_exit = jobs.clone();
    let app = api::App {
        status: status_rx,
        asks: asks_tx,
        token_sha256: config.serve.control_token_sha256,
        axes: config.axes.present(),
        jobs,
        lease,
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
        let opcua_server = opcua::start(&config, opcua_listener, feeds)
            .await
            .map_err(|e| ServeError::Io(std::io::Error::other(format!("OPC UA: {e}"))))?;
        ready(listener.local_addr()?, opcua_addr);
        let service = api::router(app).into_make_service_with_connect_info::<SocketAddr>();
        axum::serve(listener, service)
            .with_graceful_shutdown(stopped())
            .await?;
        opcua_server.cancel();
        // A job does not outlive the process that started it and reports it: it is
        // stopped (its program aborted on the daemon's stop ramp), as under systemd,
        // which stops the whole unit.
        if let Ok(Some(job)) =
            tokio::task::spawn_blocking(move || jobs_at_exit.stop_running(JOB_STOP_PATIENCE)).await
        {
            let end = match (job.state, job.exit_code) {
                (jobs::JobState::Running, _) => {
                    format!("still running after {} s", JOB_STOP_PATIENCE.as_secs())
                }
                (_, Some(code)) => format!("exit {code}"),
                (_, None) => "killed by a signal".to_owned(),
            };
            eprintln!(
                "kerf serve: stopped job {} (`{}`) at shutdown: {end}",
                job.id, job.name
            );
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passwords_are_kept_as_pbkdf2_hmac_sha256() {
        // RFC 7914, section 11: PBKDF2-HMAC-SHA256 (P="passwd", S="salt", c=1), the first
        // 32 bytes of its 64.
        let kept = kerf_config::PasswordHash {
            iterations: 1,
            salt: b"salt".to_vec(),
            hash: [
                0x55, 0xac, 0x04, 0x6e, 0x56, 0xe3, 0x08, 0x9f, 0xec, 0x16, 0x91, 0xc2, 0x25, 0x44,
                0xb6, 0x05, 0xf9, 0x41, 0x85, 0x21, 0x6d, 0xde, 0x04, 0x65, 0xe6, 0x8b, 0x9d, 0x57,
                0xc2, 0x0d, 0xac, 0xbc,
            ],
        };
        assert!(password_matches("passwd", &kept));
        assert!(!password_matches("passwe", &kept));
        // A new hash: its own salt, read back by the configuration, matching only its
        // password.
        let a = hash_password("correct horse").unwrap();
        let b = hash_password("correct horse").unwrap();
        assert_ne!(a.salt, b.salt);
        let read = kerf_config::PasswordHash::parse(&a.to_string()).expect("a kept form");
        assert_eq!(read, a);
        assert!(password_matches("correct horse", &read));
        assert!(!password_matches("correct horsf", &read));
    }
}
