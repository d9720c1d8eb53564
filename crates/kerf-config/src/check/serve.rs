//! `[serve]`: `kerf serve`'s addresses, its OPC UA Identification, the control token's
//! hash, and the OPC UA server's certificate and users.

use toml::Spanned;

use super::Checker;
use crate::raw::*;
use crate::*;

impl Checker<'_> {
    /// `[serve]`: the addresses (a socket address, IP and port), the OPC UA
    /// Identification, the control token's SHA-256 (64 hex digits), the OPC UA certificate
    /// and its users.
    pub(crate) fn serve(&self, raw: &RawServe) -> Result<ServeConfig, ConfigError> {
        let mut serve = ServeConfig::default();
        for (key, raw, out, example) in [
            ("http", &raw.http, &mut serve.http, DEFAULT_SERVE_HTTP),
            ("opcua", &raw.opcua, &mut serve.opcua, DEFAULT_SERVE_OPCUA),
        ] {
            if let Some(addr) = raw {
                *out = addr.get_ref().parse().map_err(|_| {
                    self.error(
                        addr.span(),
                        format!(
                            "`serve.{key}` must be an IP address and a port, such as \"{example}\" or \"[::1]:8080\", found `{}`",
                            addr.get_ref()
                        ),
                    )
                })?;
            }
        }
        for (key, raw, out) in [
            ("manufacturer", &raw.manufacturer, &mut serve.manufacturer),
            ("model", &raw.model, &mut serve.model),
            (
                "serial_number",
                &raw.serial_number,
                &mut serve.serial_number,
            ),
        ] {
            if let Some(text) = raw {
                let t = text.get_ref();
                if t.is_empty() || t.len() > 100 || t.chars().any(char::is_control) {
                    return Err(self.error(
                        text.span(),
                        format!(
                            "`serve.{key}` must be 1 to 100 characters without control characters"
                        ),
                    ));
                }
                *out = t.clone();
            }
        }
        if let Some(token) = &raw.control_token_sha256 {
            let hash: Option<[u8; 32]> = from_hex(token.get_ref()).and_then(|b| b.try_into().ok());
            let Some(hash) = hash else {
                return Err(self.error(
                    token.span(),
                    "`serve.control_token_sha256` must be the SHA-256 of the control token, 64 hex digits (`kerf serve --hash-token` prints it), not the token itself".to_string(),
                ));
            };
            serve.control_token_sha256 = Some(hash);
        }
        self.opcua_security(raw, &mut serve)?;
        Ok(serve)
    }

    /// `serve.opcua_certificate`, `opcua_private_key`, `opcua_pki_dir` and `opcua_users`:
    /// the certificate and its key go together, users need them (a password must not
    /// cross the network in clear), each user once with a kept password hash and a role.
    fn opcua_security(&self, raw: &RawServe, serve: &mut ServeConfig) -> Result<(), ConfigError> {
        let path = |key: &str, p: &Option<Spanned<String>>| match p {
            None => Ok(None),
            Some(t) if t.get_ref().is_empty() => Err(self.error(
                t.span(),
                format!("`serve.{key}` must name a file, found an empty string"),
            )),
            Some(t) => Ok(Some(self.dir.join(t.get_ref()))),
        };
        serve.opcua_certificate = path("opcua_certificate", &raw.opcua_certificate)?;
        serve.opcua_private_key = path("opcua_private_key", &raw.opcua_private_key)?;
        serve.opcua_pki_dir = path("opcua_pki_dir", &raw.opcua_pki_dir)?;
        match (&raw.opcua_certificate, &raw.opcua_private_key) {
            (Some(c), None) => {
                return Err(self.error(
                    c.span(),
                    "`serve.opcua_certificate` needs its private key, `serve.opcua_private_key` (PEM)".to_string(),
                ));
            }
            (None, Some(k)) => {
                return Err(self.error(
                    k.span(),
                    "`serve.opcua_private_key` needs its certificate, `serve.opcua_certificate` (.der or .pem)".to_string(),
                ));
            }
            (Some(c), Some(_)) => {
                let name = c.get_ref();
                if !(name.ends_with(".der") || name.ends_with(".pem")) {
                    return Err(self.error(
                        c.span(),
                        format!(
                            "`serve.opcua_certificate` must be a .der or .pem file, found `{name}`"
                        ),
                    ));
                }
            }
            (None, None) => {}
        }
        let Some(users) = &raw.opcua_users else {
            return Ok(());
        };
        if !users.get_ref().is_empty() && raw.opcua_certificate.is_none() {
            return Err(self.error(
                users.span(),
                "`serve.opcua_users` need `serve.opcua_certificate` and `serve.opcua_private_key`: users log in on the secure endpoints only, so that no password crosses the network in clear".to_string(),
            ));
        }
        for user in users.get_ref() {
            let name = user.name.get_ref();
            if name.is_empty() || name.len() > 64 || name.chars().any(char::is_control) {
                return Err(self.error(
                    user.name.span(),
                    "`serve.opcua_users`: a `name` is 1 to 64 characters without control characters".to_string(),
                ));
            }
            if serve.opcua_users.iter().any(|u| u.name == *name) {
                return Err(self.error(
                    user.name.span(),
                    format!("`serve.opcua_users`: the user `{name}` is given twice"),
                ));
            }
            let Some(password) = PasswordHash::parse(user.password_hash.get_ref()) else {
                return Err(self.error(
                    user.password_hash.span(),
                    format!("`serve.opcua_users`: `password_hash` must be `{PASSWORD_HASH_SCHEME}$ITERATIONS$SALT$HASH` with at least {MIN_PASSWORD_ITERATIONS} iterations, a salt of 8 to 64 bytes and a 32-byte hash in hex (`kerf serve --hash-password` prints it from the password on standard input), never the password itself"),
                ));
            };
            let role = match user.role.get_ref().as_str() {
                "viewer" => OpcuaRole::Viewer,
                "operator" => OpcuaRole::Operator,
                other => {
                    return Err(self.error(
                        user.role.span(),
                        format!("`serve.opcua_users`: `role` must be \"viewer\" or \"operator\", found `{other}`"),
                    ));
                }
            };
            serve.opcua_users.push(OpcuaUser {
                name: name.clone(),
                password,
                role,
            });
        }
        Ok(())
    }
}
