//! `[serve]`: `kerf serve`, the web page, JSON API and (later) OPC UA gateway beside the
//! daemon.

use std::net::SocketAddr;

/// The default address of the web page and JSON API: loopback only.
pub const DEFAULT_SERVE_HTTP: &str = "127.0.0.1:8080";

/// `[serve]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServeConfig {
    /// `http`: where the web page and the JSON API listen.
    pub http: SocketAddr,
    /// `control_token_sha256`: the SHA-256 of the token a client presents (`Authorization:
    /// Bearer TOKEN`) to control the machine; `None`: nobody controls it through `kerf
    /// serve`, everybody may watch.
    pub control_token_sha256: Option<[u8; 32]>,
}

impl Default for ServeConfig {
    fn default() -> Self {
        ServeConfig {
            http: DEFAULT_SERVE_HTTP.parse().expect("a socket address"),
            control_token_sha256: None,
        }
    }
}
