//! `[serve]`: `kerf serve`, the web page, JSON API and (later) OPC UA gateway beside the
//! daemon.

use std::net::SocketAddr;

/// The default address of the web page and JSON API: loopback only.
pub const DEFAULT_SERVE_HTTP: &str = "127.0.0.1:8080";

/// The default address of the OPC UA server: loopback only, OPC UA's registered port.
pub const DEFAULT_SERVE_OPCUA: &str = "127.0.0.1:4840";

/// The default manufacturer in the OPC UA Identification.
pub const DEFAULT_MANUFACTURER: &str = "Kerf";

/// The default model in the OPC UA Identification.
pub const DEFAULT_MODEL: &str = "Kerf CNC control";

/// `[serve]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServeConfig {
    /// `http`: where the web page and the JSON API listen.
    pub http: SocketAddr,
    /// `opcua`: where the OPC UA server listens.
    pub opcua: SocketAddr,
    /// `manufacturer`: the OPC UA Identification's Manufacturer.
    pub manufacturer: String,
    /// `model`: the OPC UA Identification's Model.
    pub model: String,
    /// `serial_number`: the OPC UA Identification's SerialNumber; empty: the machine's name.
    pub serial_number: String,
    /// `control_token_sha256`: the SHA-256 of the token a client presents (`Authorization:
    /// Bearer TOKEN`) to control the machine; `None`: nobody controls it through `kerf
    /// serve`, everybody may watch.
    pub control_token_sha256: Option<[u8; 32]>,
}

impl Default for ServeConfig {
    fn default() -> Self {
        ServeConfig {
            http: DEFAULT_SERVE_HTTP.parse().expect("a socket address"),
            opcua: DEFAULT_SERVE_OPCUA.parse().expect("a socket address"),
            manufacturer: DEFAULT_MANUFACTURER.to_owned(),
            model: DEFAULT_MODEL.to_owned(),
            serial_number: String::new(),
            control_token_sha256: None,
        }
    }
}
