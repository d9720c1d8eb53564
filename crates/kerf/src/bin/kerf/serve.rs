//! `kerf serve`: the web page and the JSON API of the machine (docs/API.md).

use std::io::{self, BufRead, Write};
use std::net::SocketAddr;

use clap::Args;

use crate::machine::MachineArgs;
use crate::{Failure, load_config};

#[derive(Args)]
pub struct ServeArgs {
    #[command(flatten)]
    machine: MachineArgs,
    /// Where the page and the API listen, IP:PORT (port 0: any free one); default the
    /// configuration's `serve.http`, 127.0.0.1:8080.
    #[arg(long, value_name = "ADDR:PORT")]
    http: Option<SocketAddr>,
    /// Where the OPC UA server listens, IP:PORT (port 0: any free one); default the
    /// configuration's `serve.opcua`, 127.0.0.1:4840.
    #[arg(long, value_name = "ADDR:PORT")]
    opcua: Option<SocketAddr>,
    /// Read a control token from standard input (one line) and print its SHA-256, the
    /// value of `serve.control_token_sha256`; serves nothing.
    #[arg(long, conflicts_with = "hash_password")]
    hash_token: bool,
    /// Read an OPC UA user's password from standard input (one line) and print its salted
    /// hash (PBKDF2-HMAC-SHA256), the `password_hash` of `serve.opcua_users`; serves
    /// nothing.
    #[arg(long)]
    hash_password: bool,
}

/// `kerf serve`.
pub fn run(args: &ServeArgs) -> Result<(), Failure> {
    if args.hash_token {
        let mut line = String::new();
        io::stdin().lock().read_line(&mut line)?;
        let token = line.trim_end_matches(['\r', '\n']);
        if token.len() < 16 {
            return Err(Failure::Error(
                "kerf: error: a control token must be at least 16 characters (e.g. `openssl rand -hex 16`)"
                    .into(),
            ));
        }
        let hash = kerf::serve::hash_token(token.as_bytes());
        writeln!(io::stdout().lock(), "{}", kerf::serve::hex(&hash))?;
        return Ok(());
    }
    if args.hash_password {
        let mut line = String::new();
        io::stdin().lock().read_line(&mut line)?;
        let password = line.trim_end_matches(['\r', '\n']);
        if password.len() < 8 {
            return Err(Failure::Error(
                "kerf: error: an OPC UA password must be at least 8 characters".into(),
            ));
        }
        let hash = kerf::serve::hash_password(password)
            .map_err(|e| Failure::Error(format!("kerf: error: no random salt: {e}")))?;
        writeln!(io::stdout().lock(), "{hash}")?;
        return Ok(());
    }
    let config = load_config(args.machine.config.as_deref())?;
    let http = args.http.unwrap_or(config.serve.http);
    let opcua = args.opcua.unwrap_or(config.serve.opcua);
    let machine = config.machine.clone();
    let control = if config.serve.control_token_sha256.is_some() {
        "control with the configured token"
    } else {
        "watching only (no serve.control_token_sha256)"
    };
    let config_path = args.machine.config.clone();
    kerf::serve::run(config, config_path, http, opcua, |addr, opcua| {
        let _ = writeln!(
            io::stderr().lock(),
            "kerf serve: machine `{machine}` on http://{addr}/ ({control}) and opc.tcp://{opcua}/"
        );
    })
    .map_err(|e| Failure::Error(format!("kerf: error: {e}")))
}
