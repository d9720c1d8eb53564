//! `[serve]`: addresses, Identification, the control token's hash, the OPC UA certificate
//! and users.

use crate::tests_ethercat::{at, load, refused};
use crate::tests_homing::machine;
use crate::*;

fn config(text: &str) -> Config {
    load(text).unwrap_or_else(|e| panic!("refused: {e}\n{text}"))
}

#[test]
fn serve_takes_a_socket_address_and_a_token_hash_never_the_token() {
    let c = config(&machine(""));
    assert_eq!(c.serve.http, "127.0.0.1:8080".parse().unwrap());
    assert_eq!(c.serve.control_token_sha256, None);
    // SHA-256("kerf"), from `printf kerf | sha256sum`.
    let hash = "ffc73d5ae8541990e4166e58bcbc85bfe63730015a1ae15616f228b997b953ba";
    let c = config(&machine(&format!(
        "[serve]\nhttp = \"[::1]:9000\"\ncontrol_token_sha256 = \"{hash}\"\n"
    )));
    assert_eq!(c.serve.http, "[::1]:9000".parse().unwrap());
    assert_eq!(c.serve.opcua, "127.0.0.1:4840".parse().unwrap());
    assert_eq!(
        (
            c.serve.manufacturer.as_str(),
            c.serve.serial_number.as_str()
        ),
        ("Kerf", "")
    );
    let named = config(&machine(
        "[serve]\nopcua = \"0.0.0.0:4841\"\nmanufacturer = \"Acme\"\nmodel = \"M1\"\nserial_number = \"42\"\n",
    ));
    assert_eq!(named.serve.opcua, "0.0.0.0:4841".parse().unwrap());
    let s = &named.serve;
    assert_eq!(
        (
            s.manufacturer.as_str(),
            s.model.as_str(),
            s.serial_number.as_str()
        ),
        ("Acme", "M1", "42")
    );
    let bytes = c.serve.control_token_sha256.expect("a hash");
    assert_eq!((bytes[0], bytes[1], bytes[31]), (0xff, 0xc7, 0xba));
    for (line, needle, message) in [
        (
            "http = \"localhost:80\"\n",
            "\"localhost:80\"",
            "`serve.http` must be an IP address and a port, such as \"127.0.0.1:8080\" or \"[::1]:8080\", found `localhost:80`",
        ),
        (
            "opcua = \"4840\"\n",
            "\"4840\"",
            "`serve.opcua` must be an IP address and a port, such as \"127.0.0.1:4840\" or \"[::1]:8080\", found `4840`",
        ),
        (
            "model = \"\"\n",
            "\"\"",
            "`serve.model` must be 1 to 100 characters without control characters",
        ),
        (
            "control_token_sha256 = \"kerf\"\n",
            "\"kerf\"",
            "`serve.control_token_sha256` must be the SHA-256 of the control token, 64 hex digits (`kerf serve --hash-token` prints it), not the token itself",
        ),
    ] {
        let text = machine(&format!("[serve]\n{line}"));
        assert_eq!(refused(&text), format!("{}{message}", at(&text, needle)));
    }
    let text = machine("[serve]\nport = 80\n");
    assert!(
        refused(&text).contains(
            "unknown key `serve.port` (known here: `http`, `opcua`, `manufacturer`, `model`, `serial_number`, `control_token_sha256`, `opcua_certificate`, `opcua_private_key`, `opcua_pki_dir`, `opcua_users`)"
        ),
        "{}",
        refused(&text)
    );
}

/// A password hash of the right form (its value is not checked here).
const HASH: &str = "pbkdf2-sha256$600000$000102030405060708090a0b0c0d0e0f$55ac046e56e3089fec1691c22544b605f94185216dde0465e68b9d57c20dacbc";

#[test]
fn opcua_users_need_the_certificate_a_kept_password_hash_and_a_role() {
    let c = config(&machine(""));
    assert!(c.serve.opcua_users.is_empty() && c.serve.opcua_certificate.is_none());
    let text = machine(&format!(
        "[serve]\nopcua_certificate = \"pki/kerf.der\"\nopcua_private_key = \"pki/kerf.pem\"\n\
         opcua_users = [\n  {{ name = \"op\", password_hash = \"{HASH}\", role = \"operator\" }},\n  \
         {{ name = \"shop\", password_hash = \"{HASH}\", role = \"viewer\" }},\n]\n"
    ));
    let c = config(&text);
    let s = &c.serve;
    assert!(
        s.opcua_certificate
            .as_ref()
            .unwrap()
            .ends_with("pki/kerf.der")
    );
    assert!(
        s.opcua_private_key
            .as_ref()
            .unwrap()
            .ends_with("pki/kerf.pem")
    );
    let users: Vec<(&str, OpcuaRole)> = s
        .opcua_users
        .iter()
        .map(|u| (u.name.as_str(), u.role))
        .collect();
    assert_eq!(
        users,
        [("op", OpcuaRole::Operator), ("shop", OpcuaRole::Viewer)]
    );
    let p = &s.opcua_users[0].password;
    assert_eq!(
        (p.iterations, p.salt.len(), p.hash[0], p.hash[31]),
        (600_000, 16, 0x55, 0xbc)
    );
    assert_eq!(p.to_string(), HASH, "written back as read");
    assert!(
        c.machine_opcua_pki_directory()
            .ends_with(format!("{}-opcua-pki", c.machine))
    );
    let cert = "opcua_certificate = \"kerf.der\"\nopcua_private_key = \"kerf.pem\"\n";
    let user = |name: &str, hash: &str, role: &str| {
        format!(
            "opcua_users = [{{ name = \"{name}\", password_hash = \"{hash}\", role = \"{role}\" }}]\n"
        )
    };
    let few = HASH.replace("600000", "1000");
    for (lines, needle, message) in [
        (
            "opcua_certificate = \"kerf.der\"\n".to_owned(),
            "\"kerf.der\"",
            "`serve.opcua_certificate` needs its private key, `serve.opcua_private_key` (PEM)",
        ),
        (
            "opcua_private_key = \"kerf.pem\"\n".to_owned(),
            "\"kerf.pem\"",
            "`serve.opcua_private_key` needs its certificate, `serve.opcua_certificate` (.der or .pem)",
        ),
        (
            "opcua_certificate = \"kerf.crt\"\nopcua_private_key = \"kerf.pem\"\n".to_owned(),
            "\"kerf.crt\"",
            "`serve.opcua_certificate` must be a .der or .pem file, found `kerf.crt`",
        ),
        (
            user("op", HASH, "operator"),
            "[{",
            "`serve.opcua_users` need `serve.opcua_certificate` and `serve.opcua_private_key`: users log in on the secure endpoints only, so that no password crosses the network in clear",
        ),
        (
            format!("{cert}{}", user("op", "secret", "operator")),
            "\"secret\"",
            "`serve.opcua_users`: `password_hash` must be `pbkdf2-sha256$ITERATIONS$SALT$HASH` with at least 10000 iterations, a salt of 8 to 64 bytes and a 32-byte hash in hex (`kerf serve --hash-password` prints it from the password on standard input), never the password itself",
        ),
        (
            format!("{cert}{}", user("op", &few, "operator")),
            "\"pbkdf2",
            "`serve.opcua_users`: `password_hash` must be `pbkdf2-sha256$ITERATIONS$SALT$HASH` with at least 10000 iterations, a salt of 8 to 64 bytes and a 32-byte hash in hex (`kerf serve --hash-password` prints it from the password on standard input), never the password itself",
        ),
        (
            format!("{cert}{}", user("op", HASH, "admin")),
            "\"admin\"",
            "`serve.opcua_users`: `role` must be \"viewer\" or \"operator\", found `admin`",
        ),
        (
            format!("{cert}{}", user("", HASH, "viewer")),
            "\"\"",
            "`serve.opcua_users`: a `name` is 1 to 64 characters without control characters",
        ),
    ] {
        let text = machine(&format!("[serve]\n{lines}"));
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{lines}"
        );
    }
    let text = machine(&format!(
        "[serve]\n{cert}opcua_users = [{{ name = \"op\", password_hash = \"{HASH}\", role = \"operator\" }}, {{ name = \"op\", password_hash = \"{HASH}\", role = \"viewer\" }}]\n"
    ));
    assert!(
        refused(&text).ends_with("`serve.opcua_users`: the user `op` is given twice"),
        "{}",
        refused(&text)
    );
}
