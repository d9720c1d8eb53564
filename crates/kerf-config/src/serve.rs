//! `[serve]`: `kerf serve`, the web page, JSON API and OPC UA gateway beside the daemon.

use std::net::SocketAddr;
use std::path::PathBuf;

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
    /// `opcua_certificate`: the OPC UA server's application instance certificate (`.der`
    /// or `.pem`, relative to the configuration's directory); with it the server offers the
    /// secure endpoints and user logins. `None`: only the None endpoint, anonymous.
    pub opcua_certificate: Option<PathBuf>,
    /// `opcua_private_key`: the certificate's private key (PEM).
    pub opcua_private_key: Option<PathBuf>,
    /// `opcua_pki_dir`: the OPC UA certificate store (`trusted/`, `rejected/`); `None`:
    /// see `Config::machine_opcua_pki_directory`.
    pub opcua_pki_dir: Option<PathBuf>,
    /// `opcua_users`: who may log in to the OPC UA server, with their roles.
    pub opcua_users: Vec<OpcuaUser>,
}

/// What an OPC UA user may do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OpcuaRole {
    /// Read and subscribe, as an anonymous client.
    Viewer,
    /// Also call the control methods: hold, resume, the overrides.
    Operator,
}

/// A user of the OPC UA server.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OpcuaUser {
    /// The user name.
    pub name: String,
    /// The password's hash, never the password.
    pub password: PasswordHash,
    /// What the user may do.
    pub role: OpcuaRole,
}

/// How a password is kept: PBKDF2-HMAC-SHA256 with a salt of its own, written
/// `pbkdf2-sha256$ITERATIONS$SALT$HASH` (salt and hash in hex; `kerf serve
/// --hash-password` makes one).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PasswordHash {
    /// PBKDF2 iterations.
    pub iterations: u32,
    /// The salt, 8 to 64 bytes.
    pub salt: Vec<u8>,
    /// The derived key.
    pub hash: [u8; 32],
}

/// The scheme word of a [`PasswordHash`].
pub const PASSWORD_HASH_SCHEME: &str = "pbkdf2-sha256";

/// The fewest PBKDF2 iterations accepted: fewer make a stolen configuration's passwords
/// cheap to guess.
pub const MIN_PASSWORD_ITERATIONS: u32 = 10_000;

/// `bytes` as lower-case hex digits, two per byte.
pub fn to_hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The bytes of `text`, pairs of hex digits (either case); None for anything else (a sign
/// included, which `from_str_radix` alone would take).
pub(crate) fn from_hex(text: &str) -> Option<Vec<u8>> {
    if !text.len().is_multiple_of(2) || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&text[i..i + 2], 16).ok())
        .collect()
}

impl PasswordHash {
    /// Reads `pbkdf2-sha256$ITERATIONS$SALT$HASH`.
    pub fn parse(text: &str) -> Option<PasswordHash> {
        let mut parts = text.split('$');
        if parts.next()? != PASSWORD_HASH_SCHEME {
            return None;
        }
        let iterations: u32 = parts.next()?.parse().ok()?;
        let salt = from_hex(parts.next()?)?;
        let hash: [u8; 32] = from_hex(parts.next()?)?.try_into().ok()?;
        if parts.next().is_some()
            || iterations < MIN_PASSWORD_ITERATIONS
            || !(8..=64).contains(&salt.len())
        {
            return None;
        }
        Some(PasswordHash {
            iterations,
            salt,
            hash,
        })
    }
}

impl std::fmt::Display for PasswordHash {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{PASSWORD_HASH_SCHEME}${}${}${}",
            self.iterations,
            to_hex(&self.salt),
            to_hex(&self.hash)
        )
    }
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
            opcua_certificate: None,
            opcua_private_key: None,
            opcua_pki_dir: None,
            opcua_users: Vec::new(),
        }
    }
}
