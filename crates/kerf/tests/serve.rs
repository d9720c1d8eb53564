//! `kerf serve` against a live `kerfd` with simulated drives, from a plain HTTP client and
//! a WebSocket client (docs/API.md): the status, its stream at 20 Hz at most to two
//! watchers at once, control refused without the token, from another site's page, with
//! bad JSON, unknown fields or a body too large (nothing moves), and with the token a jog
//! that ends exactly where asked, and hold and cycle start of a running program; programs
//! and MDI lines run as `kerf run` and `kerf mdi` run them; the control lease (one client
//! controls, the others may only stop); the black box after a fault; the page in a real
//! browser (headless Chromium); 20 watchers that change no setpoint.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use serde_json::Value;

mod common;
use common::{MACHINE_PATIENCE, MachineEnv, Proc, read_text};
#[path = "serve/browser.rs"]
mod browser;
use browser::{Browser, decode_base64, pixels};

/// The control token of these tests, and its hash in the configuration.
const TOKEN: &str = "serve-test-token-0123456789";

/// A machine whose `[serve]` accepts [`TOKEN`], its daemon, and `kerf serve` on a free
/// port of 127.0.0.1.
struct Served {
    env: MachineEnv,
    addr: SocketAddr,
    _daemon: Proc,
    _serve: Proc,
}

fn served(tag: &str) -> Served {
    served_with(tag, &[])
}

/// [`served`], the daemon started with `daemon_args` too.
fn served_with(tag: &str, daemon_args: &[&str]) -> Served {
    let env = MachineEnv::new("kerf-serve-tests", "sv", tag, false);
    let hash = kerf::serve::hex(&kerf::serve::hash_token(TOKEN.as_bytes()));
    let text = std::fs::read_to_string(&env.config_path).unwrap();
    std::fs::write(
        &env.config_path,
        format!("{text}\n[serve]\ncontrol_token_sha256 = \"{hash}\"\n"),
    )
    .unwrap();
    let daemon = env.start_daemon_with("kerfd", daemon_args);
    let serve = Proc::start(
        "serve",
        &env.dir,
        env.kerf_command(
            &["serve"],
            &["--http", "127.0.0.1:0", "--opcua", "127.0.0.1:0"],
        ),
    );
    let deadline = Instant::now() + MACHINE_PATIENCE;
    let addr = loop {
        let said = read_text(&serve.stderr);
        if let Some(rest) = said.split("on http://").nth(1) {
            break rest.split('/').next().unwrap().parse().expect("an address");
        }
        assert!(
            Instant::now() < deadline,
            "kerf serve never listened: {said}"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    Served {
        env,
        addr,
        _daemon: daemon,
        _serve: serve,
    }
}

/// One HTTP/1.1 request (`Connection: close`): the status code and the body.
fn http(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[&str],
    body: &[u8],
) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(MACHINE_PATIENCE)).unwrap();
    let mut request = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    for h in headers {
        request.push_str(h);
        request.push_str("\r\n");
    }
    request.push_str("\r\n");
    s.write_all(request.as_bytes()).unwrap();
    // A body the server refuses before reading it all may end the connection early.
    let _ = s.write_all(body);
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer);
    let text = String::from_utf8_lossy(&answer).to_string();
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("not an HTTP answer: {text}"));
    let body = text
        .split_once("\r\n\r\n")
        .map(|(_, b)| b.to_string())
        .unwrap_or_default();
    (code, body)
}

fn json(body: &str) -> Value {
    serde_json::from_str(body).unwrap_or_else(|e| panic!("not JSON ({e}): {body}"))
}

/// `POST /api/v1/control` with `body` and the token (unless `token` is None).
fn control(addr: SocketAddr, token: Option<&str>, body: &str) -> (u16, Value) {
    let auth = token.map(|t| format!("Authorization: Bearer {t}"));
    let mut headers = vec!["Content-Type: application/json"];
    if let Some(a) = &auth {
        headers.push(a);
    }
    let (code, text) = http(addr, "POST", "/api/v1/control", &headers, body.as_bytes());
    (code, json(&text))
}

/// `POST PATH` with the JSON `body`, the token and, when given, the client's id in
/// `Kerf-Client`.
fn post_as(addr: SocketAddr, path: &str, client: Option<&str>, body: &str) -> (u16, Value) {
    let auth = format!("Authorization: Bearer {TOKEN}");
    let id = client.map(|c| format!("Kerf-Client: {c}"));
    let mut headers = vec!["Content-Type: application/json", auth.as_str()];
    if let Some(i) = &id {
        headers.push(i);
    }
    let (code, text) = http(addr, "POST", path, &headers, body.as_bytes());
    (code, json(&text))
}

/// `GET /api/v1/control/lease` as `client`: the lease, `null` when nobody holds it.
fn lease_as(addr: SocketAddr, client: &str) -> Value {
    let id = format!("Kerf-Client: {client}");
    let (code, text) = http(addr, "GET", "/api/v1/control/lease", &[&id], b"");
    assert_eq!(code, 200, "{text}");
    json(&text)["lease"].clone()
}

/// The API's status object, waited for until `done` holds.
fn status_until(addr: SocketAddr, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + MACHINE_PATIENCE;
    loop {
        let (code, body) = http(addr, "GET", "/api/v1/status", &[], b"");
        assert_eq!(code, 200, "{body}");
        let m = json(&body);
        if m["connected"] == true && done(&m["status"]) {
            return m["status"].clone();
        }
        assert!(Instant::now() < deadline, "never {what}: {m}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn the_page_the_status_and_its_stream_are_served_to_several_watchers_at_20_hz_at_most() {
    let s = served("watch");
    let (code, page) = http(s.addr, "GET", "/", &[], b"");
    assert_eq!(code, 200);
    assert!(page.contains("<title>Kerf</title>"), "{page}");
    for path in ["/app.js", "/style.css"] {
        assert_eq!(http(s.addr, "GET", path, &[], b"").0, 200, "{path}");
    }
    let (code, body) = http(s.addr, "GET", "/nowhere", &[], b"");
    assert_eq!(
        (code, json(&body)["error"]["code"].clone()),
        (404, Value::from("not_found"))
    );
    let st = status_until(s.addr, "idle", |st| st["state"] == "idle");
    assert_eq!(st["machine"], Value::from(s.env.machine.clone()));
    // The same object as `kerf status --json`'s, but for what moves (cycles, time).
    let cli = s.env.status();
    for key in [
        "machine",
        "state",
        "position",
        "override_pct",
        "axes",
        "dro",
    ] {
        assert_eq!(st[key], cli[key], "{key}");
    }
    // Two watchers at once; each message one status, sent at most every 50 ms of the
    // link's clock (`t_ms`, when it read the status), in order.
    let url = format!("ws://{}/api/v1/ws", s.addr);
    let mut watchers: Vec<_> = (0..2)
        .map(|_| {
            let stream = TcpStream::connect(s.addr).unwrap();
            stream.set_read_timeout(Some(MACHINE_PATIENCE)).unwrap();
            tungstenite::client(url.as_str(), stream)
                .expect("a WebSocket")
                .0
        })
        .collect();
    for w in &mut watchers {
        let mut last: Option<(u64, u64)> = None;
        for _ in 0..8 {
            let m = match w.read().expect("a message") {
                tungstenite::Message::Text(t) => json(t.as_str()),
                other => panic!("not text: {other:?}"),
            };
            assert_eq!(m["api"], 1);
            assert_eq!(m["connected"], true, "{m}");
            assert_eq!(m["status"]["machine"], Value::from(s.env.machine.clone()));
            let (seq, t_ms) = (m["seq"].as_u64().unwrap(), m["t_ms"].as_u64().unwrap());
            if let Some((s0, t0)) = last {
                assert!(seq > s0, "seq {s0} then {seq}");
                assert!(t_ms >= t0 + 49, "two messages {} ms apart", t_ms - t0);
            }
            last = Some((seq, t_ms));
        }
    }
}

#[test]
fn control_is_refused_without_the_token_from_another_site_or_malformed_and_nothing_moves() {
    let s = served("refuse");
    let before = status_until(s.addr, "idle", |st| st["state"] == "idle");
    let step = r#"{"command":"jog_step","axis":"X","distance":5}"#;
    for (token, headers, body, code, reason) in [
        (None, &[][..], step, 401, "unauthorized"),
        (
            Some("wrong-token-0123456789"),
            &[][..],
            step,
            401,
            "unauthorized",
        ),
        (
            Some(TOKEN),
            &["Origin: http://elsewhere.example"][..],
            step,
            403,
            "cross_origin",
        ),
        (
            Some(TOKEN),
            &["Sec-Fetch-Site: cross-site"][..],
            step,
            403,
            "cross_origin",
        ),
        (Some(TOKEN), &[][..], "{\"command\":", 400, "bad_request"),
        (
            Some(TOKEN),
            &[][..],
            r#"{"command":"jog_step","axis":"X","distance":5,"x":1}"#,
            400,
            "bad_request",
        ),
        (
            Some(TOKEN),
            &[][..],
            r#"{"command":"launch"}"#,
            400,
            "bad_request",
        ),
        (
            Some(TOKEN),
            &[][..],
            r#"{"command":"jog_step","axis":"W","distance":5}"#,
            400,
            "bad_request",
        ),
        (
            Some(TOKEN),
            &[][..],
            r#"{"command":"jog_step","axis":"X","distance":5000}"#,
            409,
            "refused",
        ),
    ] {
        let auth = token.map(|t| format!("Authorization: Bearer {t}"));
        let mut all: Vec<&str> = headers.to_vec();
        if let Some(a) = &auth {
            all.push(a);
        }
        let (got, text) = http(s.addr, "POST", "/api/v1/control", &all, body.as_bytes());
        let answer = json(&text);
        assert_eq!(
            (got, answer["error"]["code"].clone()),
            (code, Value::from(reason)),
            "{body} {headers:?}: {answer}"
        );
        assert!(
            answer["error"]["message"]
                .as_str()
                .is_some_and(|m| !m.is_empty())
        );
    }
    // Too large: refused before it is read.
    let big = format!(r#"{{"command":"hold","pad":"{}"}}"#, "x".repeat(100_000));
    let (code, text) = http(
        s.addr,
        "POST",
        "/api/v1/control",
        &[&format!("Authorization: Bearer {TOKEN}")],
        big.as_bytes(),
    );
    assert_eq!(
        (code, json(&text)["error"]["code"].clone()),
        (413, Value::from("too_large"))
    );
    // Nothing moved, and every refusal was logged with the client's address.
    let after = status_until(s.addr, "idle", |st| st["state"] == "idle");
    assert_eq!(after["position"], before["position"]);
    let log = read_text(&s.env.dir.join("serve.stderr"));
    assert_eq!(
        log.matches("kerf serve: refused a control request from 127.0.0.1:")
            .count(),
        10,
        "{log}"
    );
}

#[test]
fn with_the_token_a_jog_ends_where_asked_and_a_program_holds_and_resumes() {
    let s = served("control");
    let before = status_until(s.addr, "idle", |st| st["state"] == "idle");
    let x0 = before["position"]["x"].as_f64().unwrap();
    let (code, answer) = control(
        s.addr,
        Some(TOKEN),
        r#"{"command":"jog_step","axis":"x","distance":2.5,"speed":20}"#,
    );
    assert_eq!(code, 200, "{answer}");
    assert_eq!(answer["ok"], true);
    // Exactly there (waited for until it is, or the test fails after the patience).
    status_until(s.addr, "X exactly 2.5 mm on", |st| {
        st["state"] == "idle" && st["position"]["x"].as_f64() == Some(x0 + 2.5)
    });
    let (code, answer) = control(
        s.addr,
        Some(TOKEN),
        r#"{"command":"override","percent":50}"#,
    );
    assert_eq!(
        (code, answer["status"]["override_pct"].clone()),
        (200, Value::from(50.0))
    );
    // A program of 4 s at 50 %: held while it runs, then resumed to its end.
    let program = s.env.write("long.ngc", "G21 G90 G1 X40 F1200\nG1 X0\nM2\n");
    let mut run = Proc::start(
        "run",
        &s.env.dir,
        s.env.kerf_command(&["run"], &[program.to_str().unwrap()]),
    );
    status_until(s.addr, "running", |st| st["state"] == "running");
    let (code, answer) = control(s.addr, Some(TOKEN), r#"{"command":"hold"}"#);
    assert_eq!(code, 200, "{answer}");
    // Held: at rest on the path (two statuses 100 ms apart agree), and it stays there.
    let deadline = Instant::now() + MACHINE_PATIENCE;
    let x_held = loop {
        let a = status_until(s.addr, "held", |st| st["state"] == "holding");
        std::thread::sleep(Duration::from_millis(100));
        let b = status_until(s.addr, "held", |st| st["state"] == "holding");
        if a["position"] == b["position"] {
            break b["position"]["x"].as_f64().unwrap();
        }
        assert!(Instant::now() < deadline, "never at rest while held: {b}");
    };
    assert!(
        x_held > 0.0 && x_held < 40.0,
        "held at X {x_held}, not on the way"
    );
    std::thread::sleep(Duration::from_millis(300));
    let still = status_until(s.addr, "still held", |st| st["state"] == "holding");
    assert_eq!(
        still["position"]["x"].as_f64().unwrap(),
        x_held,
        "moved while held"
    );
    let (code, answer) = control(s.addr, Some(TOKEN), r#"{"command":"resume"}"#);
    assert_eq!(code, 200, "{answer}");
    let exit = run.wait_within(MACHINE_PATIENCE);
    assert!(exit.success(), "kerf run: {}", run.stderr());
    let end = status_until(s.addr, "idle", |st| st["state"] == "idle");
    assert_eq!(end["position"]["x"].as_f64().unwrap(), 0.0);
}

/// `GET /api/v1/job`'s job, waited for until `done` holds.
fn job_until(addr: SocketAddr, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + MACHINE_PATIENCE;
    loop {
        let (code, body) = http(addr, "GET", "/api/v1/job", &[], b"");
        assert_eq!(code, 200, "{body}");
        let job = json(&body)["job"].clone();
        if done(&job) {
            return job;
        }
        assert!(Instant::now() < deadline, "never {what}: {job}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_program_sent_through_the_api_runs_as_kerf_run_runs_it_and_a_bad_one_comes_back_with_its_place()
{
    let s = served("program");
    let auth = format!("Authorization: Bearer {TOKEN}");
    let post = |name: &str, text: &[u8], headers: &[&str]| {
        let (code, body) = http(
            s.addr,
            "POST",
            &format!("/api/v1/program?name={name}"),
            headers,
            text,
        );
        (code, json(&body))
    };
    assert_eq!(
        json(&http(s.addr, "GET", "/api/v1/job", &[], b"").1)["job"],
        Value::Null
    );
    // Refused, and nothing runs: no token, a name that is a path, too large.
    let part = b"G21 G90\nG1 X12.5 Y-3 F3000\nG0 X0 Y0\nM2\n";
    assert_eq!(post("part.ngc", part, &[]).0, 401);
    let (code, answer) = post("..%2Fescape.ngc", part, &[&auth]);
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (400, Value::from("bad_request")),
        "{answer}"
    );
    let huge = vec![b'\n'; kerf::serve::jobs::PROGRAM_LIMIT + 1];
    let (code, answer) = post("huge.ngc", &huge, &[&auth]);
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (413, Value::from("too_large")),
        "{answer}"
    );
    assert_eq!(
        json(&http(s.addr, "GET", "/api/v1/job", &[], b"").1)["job"],
        Value::Null
    );
    // A program with an error: `kerf run` refuses it before anything moves, and its
    // `FILE:LINE:COL: error:` comes back in the job.
    let before = status_until(s.addr, "idle", |st| st["state"] == "idle");
    let (code, answer) = post("bad.ngc", b"G21 G90\nG1 X10 F100\nG1 X20 Q\nM2\n", &[&auth]);
    assert_eq!(code, 202, "{answer}");
    let job = job_until(s.addr, "the bad job ended", |j| j["state"] != "running");
    assert_eq!(job["state"], "failed", "{job}");
    assert_eq!(job["exit_code"], 2, "{job}");
    let kept = s
        .env
        .dir
        .join(format!("{}-programs/bad.ngc", s.env.machine));
    let place = format!("{}:3:", kept.display());
    assert!(
        job["messages"].as_array().unwrap().iter().any(|m| m
            .as_str()
            .is_some_and(|m| m.starts_with(&place) && m.contains(": error: "))),
        "no {place}…: error: in {job}"
    );
    assert_eq!(
        status_until(s.addr, "idle", |st| st["state"] == "idle")["position"],
        before["position"]
    );
    // While a job runs, a second program is refused; the first, aborted, is never
    // reported finished.
    let (code, answer) = post("long.ngc", b"G21 G90\nG1 X200 F600\nM2\n", &[&auth]);
    assert_eq!(code, 202, "{answer}");
    status_until(s.addr, "running", |st| st["state"] == "running");
    let (code, again) = post("part.ngc", part, &[&auth]);
    assert_eq!(
        (code, again["error"]["code"].clone()),
        (409, Value::from("busy")),
        "{again}"
    );
    let (code, answer) = control(s.addr, Some(TOKEN), r#"{"command":"abort"}"#);
    assert_eq!(code, 200, "{answer}");
    let job = job_until(s.addr, "the aborted job ended", |j| j["state"] != "running");
    assert_eq!(job["state"], "failed", "{job}");
    assert_ne!(job["exit_code"], 0, "{job}");
    let stopped = status_until(s.addr, "idle", |st| st["state"] == "idle");
    let x_stopped = stopped["position"]["x"].as_f64().unwrap();
    assert!(x_stopped > 0.0 && x_stopped < 200.0, "{stopped}");
    // A good one runs to its end, exactly as `kerf run` of the same file: it starts from
    // where the machine stands and ends at 0, 0.
    let (code, answer) = post("part.ngc", part, &[&auth]);
    assert_eq!(code, 202, "{answer}");
    assert_eq!(answer["job"]["name"], "part.ngc");
    assert_eq!(answer["job"]["state"], "running");
    let job = job_until(s.addr, "the part ended", |j| j["state"] != "running");
    assert_eq!(
        (job["state"].clone(), job["exit_code"].clone()),
        (Value::from("finished"), Value::from(0)),
        "{job}"
    );
    let end = status_until(s.addr, "idle", |st| st["state"] == "idle");
    assert_eq!(end["position"]["x"], 0.0);
    assert_eq!(end["position"]["y"], 0.0);
    let kept = s
        .env
        .dir
        .join(format!("{}-programs/part.ngc", s.env.machine));
    assert_eq!(std::fs::read(kept).unwrap(), part);
}

/// The machine's work position on `axis` (the DRO), mm.
fn work(status: &Value, axis: &str) -> f64 {
    status["dro"]["work"][axis]
        .as_f64()
        .unwrap_or_else(|| panic!("no work position of {axis}: {status}"))
}

#[test]
fn mdi_lines_from_the_api_run_as_kerf_mdi_runs_them_and_a_bad_one_comes_back_with_its_place() {
    let s = served("mdi");
    let mdi = |line: &str| {
        post_as(
            s.addr,
            "/api/v1/mdi",
            None,
            &serde_json::json!({ "line": line }).to_string(),
        )
    };
    let finished = |what: &str| {
        let job = job_until(s.addr, what, |j| j["state"] != "running");
        assert_eq!(
            (job["state"].clone(), job["exit_code"].clone()),
            (Value::from("finished"), Value::from(0)),
            "{what}: {job}"
        );
        status_until(s.addr, "idle", |st| st["state"] == "idle")
    };
    // A line goes where it says, in work coordinates.
    let (code, answer) = mdi("G0 X12.5 Y-3");
    assert_eq!(code, 202, "{answer}");
    assert_eq!(
        (answer["job"]["kind"].clone(), answer["job"]["name"].clone()),
        (Value::from("mdi"), Value::from("G0 X12.5 Y-3"))
    );
    let at = finished("the first line");
    assert!((work(&at, "x") - 12.5).abs() < 1e-9, "{at}");
    assert!((work(&at, "y") + 3.0).abs() < 1e-9, "{at}");
    // Each line starts in a program's modal state (docs/API.md): the G91 of one line does
    // not carry into the next, which is absolute again.
    let (code, answer) = mdi("G91 G0 X1");
    assert_eq!(code, 202, "{answer}");
    let at = finished("the incremental line");
    assert!((work(&at, "x") - 13.5).abs() < 1e-9, "{at}");
    let (code, answer) = mdi("G0 X1");
    assert_eq!(code, 202, "{answer}");
    let at = finished("the absolute line");
    assert!((work(&at, "x") - 1.0).abs() < 1e-9, "{at}");
    // A line the interpreter refuses: the error with its place, the job failed, nothing
    // moved.
    let (code, answer) = mdi("G1 X40");
    assert_eq!(code, 202, "{answer}");
    let job = job_until(s.addr, "the refused line", |j| j["state"] != "running");
    assert_eq!(job["state"], "failed", "{job}");
    assert_ne!(job["exit_code"], 0, "{job}");
    let said = job["messages"].to_string();
    assert!(said.contains("mdi:1:") && said.contains("error:"), "{job}");
    let still = status_until(s.addr, "idle", |st| st["state"] == "idle");
    assert_eq!(still["position"], at["position"], "a refused line moved");
    // Not one line, too long, unknown fields, bad JSON: refused before anything runs.
    let before = job_until(s.addr, "the last job", |_| true)["id"].clone();
    for body in [
        r#"{"line":"G0 X5\nG0 X6"}"#.to_owned(),
        r#"{"line":"   "}"#.to_owned(),
        serde_json::json!({ "line": format!("G0 X5 ({})", "x".repeat(300)) }).to_string(),
        r#"{"line":"G0 X5","dialect":"fagor"}"#.to_owned(),
        r#"{"line":"G0 X5""#.to_owned(),
    ] {
        let (code, answer) = post_as(s.addr, "/api/v1/mdi", None, &body);
        assert_eq!(
            (code, answer["error"]["code"].clone()),
            (400, Value::from("bad_request")),
            "{body}: {answer}"
        );
    }
    assert_eq!(job_until(s.addr, "the last job", |_| true)["id"], before);
    // A line while another runs: busy; the running one is aborted from the API.
    let (code, answer) = mdi("G1 X80 F300");
    assert_eq!(code, 202, "{answer}");
    status_until(s.addr, "the slow line moving", |st| {
        st["state"] == "running"
    });
    let (code, answer) = mdi("G0 X0");
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (409, Value::from("busy")),
        "{answer}"
    );
    let (code, answer) = control(s.addr, Some(TOKEN), r#"{"command":"abort"}"#);
    assert_eq!(code, 200, "{answer}");
    let job = job_until(s.addr, "the aborted line", |j| j["state"] != "running");
    assert_eq!(job["state"], "failed", "{job}");
    let stopped = status_until(s.addr, "idle", |st| st["state"] == "idle");
    let x = work(&stopped, "x");
    assert!(
        x > 1.0 && x < 80.0,
        "the aborted line stopped short: {stopped}"
    );
    // A touch-off by MDI (G10 L20: G54 so that X here reads 0): the DRO of the status
    // follows the parameter file `kerf mdi` wrote, the machine did not move.
    let (code, answer) = mdi("G10 L20 P1 X0");
    assert_eq!(code, 202, "{answer}");
    finished("the touch-off");
    let touched = status_until(s.addr, "X reading 0 in G54", |st| {
        st["dro"]["work"]["x"]
            .as_f64()
            .is_some_and(|x| x.abs() < 1e-9)
    });
    assert_eq!(touched["position"]["x"], stopped["position"]["x"]);
    assert_eq!(touched["dro"]["work_offset"]["x"], stopped["position"]["x"]);
}

#[test]
fn one_client_holds_control_the_others_may_only_stop_and_a_take_over_is_explicit() {
    let s = served("lease");
    const A: &str = "page-aaaaaaaa";
    const B: &str = "page-bbbbbbbb";
    let lease = "/api/v1/control/lease";
    assert_eq!(lease_as(s.addr, A), Value::Null, "nobody holds it at first");
    // Taking it needs an id; A takes it.
    let (code, answer) = post_as(s.addr, lease, None, r#"{"action":"take"}"#);
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (400, Value::from("bad_request")),
        "{answer}"
    );
    let (code, answer) = post_as(s.addr, lease, Some("bad id"), r#"{"action":"take"}"#);
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (400, Value::from("bad_request")),
        "{answer}"
    );
    let (code, answer) = post_as(s.addr, lease, Some(A), r#"{"action":"take"}"#);
    assert_eq!(code, 200, "{answer}");
    assert_eq!(answer["lease"]["yours"], true, "{answer}");
    assert_eq!(lease_as(s.addr, B)["yours"], false);
    assert!(
        lease_as(s.addr, B)["peer"]
            .as_str()
            .unwrap()
            .starts_with("127.0.0.1:")
    );
    // A moves the machine; B, and a client without an id, may not start anything.
    let (code, answer) = post_as(s.addr, "/api/v1/mdi", Some(A), r#"{"line":"G1 X80 F300"}"#);
    assert_eq!(code, 202, "{answer}");
    status_until(s.addr, "A's line moving", |st| st["state"] == "running");
    for (client, body) in [
        (Some(B), r#"{"command":"override","percent":150}"#),
        (None, r#"{"command":"override","percent":150}"#),
        (Some(B), r#"{"command":"jog","axis":"y","direction":"+"}"#),
    ] {
        let (code, answer) = post_as(s.addr, "/api/v1/control", client, body);
        assert_eq!(
            (code, answer["error"]["code"].clone()),
            (409, Value::from("controlled_elsewhere")),
            "{client:?} {body}: {answer}"
        );
    }
    let (code, answer) = post_as(s.addr, "/api/v1/mdi", Some(B), r#"{"line":"G0 Y5"}"#);
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (409, Value::from("controlled_elsewhere")),
        "{answer}"
    );
    // But B may stop it: hold (and not resume), then abort.
    let (code, answer) = post_as(s.addr, "/api/v1/control", Some(B), r#"{"command":"hold"}"#);
    assert_eq!(code, 200, "{answer}");
    status_until(s.addr, "held by B", |st| st["state"] == "holding");
    let (code, answer) = post_as(
        s.addr,
        "/api/v1/control",
        Some(B),
        r#"{"command":"resume"}"#,
    );
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (409, Value::from("controlled_elsewhere")),
        "{answer}"
    );
    let (code, answer) = post_as(s.addr, "/api/v1/control", Some(B), r#"{"command":"abort"}"#);
    assert_eq!(code, 200, "{answer}");
    job_until(s.addr, "the aborted line", |j| j["state"] != "running");
    status_until(s.addr, "idle", |st| st["state"] == "idle");
    // B cannot take it without force; with force it can, and then A is refused.
    let (code, answer) = post_as(s.addr, lease, Some(B), r#"{"action":"take"}"#);
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (409, Value::from("controlled_elsewhere")),
        "{answer}"
    );
    let (code, answer) = post_as(s.addr, lease, Some(B), r#"{"action":"take","force":true}"#);
    assert_eq!(code, 200, "{answer}");
    assert_eq!(lease_as(s.addr, A)["yours"], false);
    let (code, answer) = post_as(
        s.addr,
        "/api/v1/control",
        Some(A),
        r#"{"command":"override","percent":120}"#,
    );
    assert_eq!(
        (code, answer["error"]["code"].clone()),
        (409, Value::from("controlled_elsewhere")),
        "{answer}"
    );
    let (code, answer) = post_as(
        s.addr,
        "/api/v1/control",
        Some(B),
        r#"{"command":"override","percent":120}"#,
    );
    assert_eq!(code, 200, "{answer}");
    assert_eq!(answer["status"]["override_pct"], 120.0, "{answer}");
    // Released, anyone may control again.
    let (code, answer) = post_as(s.addr, lease, Some(B), r#"{"action":"release"}"#);
    assert_eq!(
        (code, answer["lease"].clone()),
        (200, Value::Null),
        "{answer}"
    );
    let (code, answer) = post_as(
        s.addr,
        "/api/v1/control",
        None,
        r#"{"command":"override","percent":100}"#,
    );
    assert_eq!(code, 200, "{answer}");
    // Every refusal was logged with the client's address.
    let said = read_text(&s._serve.stderr);
    assert!(said.matches("controlled_elsewhere").count() >= 7, "{said}");
    assert!(said.contains("control taken over by 127.0.0.1:"), "{said}");
}

#[test]
fn after_a_drive_fault_the_black_box_is_served_as_kerf_plot_draws_it() {
    use kerfd::worker::Injection;
    let s = served_with("blackbox", &["--test-faults"]);
    let svg = |addr| http(addr, "GET", "/api/v1/fault/blackbox.svg", &[], b"");
    let (code, body) = svg(s.addr);
    assert_eq!(
        (code, json(&body)["error"]["code"].clone()),
        (404, Value::from("not_found"))
    );
    // A jog, and a drive fault on X while it moves.
    let (code, answer) = control(
        s.addr,
        Some(TOKEN),
        r#"{"command":"jog_step","axis":"x","distance":20}"#,
    );
    assert_eq!(code, 200, "{answer}");
    status_until(s.addr, "X moving", |st| st["axes"]["x"]["jogging"] == true);
    let mut client = kerf::client::Client::connect(&s.env.machine).unwrap();
    let code = Injection::DriveFault(0).code().unwrap();
    client
        .request(kerf_proto::ControlCommand::Inject { code })
        .unwrap();
    let fault = status_until(s.addr, "the fault and its black box", |st| {
        st["state"] == "fault" && st["safety"]["dump"].is_string()
    });
    let dump = fault["safety"]["dump"].as_str().unwrap().to_owned();
    let (code, body) = svg(s.addr);
    assert_eq!(code, 200, "{body}");
    // The drawing `kerf plot` makes of the daemon's file.
    let out = s.env.path("plot.svg");
    let plot = s
        .env
        .command(
            env!("CARGO_BIN_EXE_kerf"),
            &["plot", &dump, "--out", out.to_str().unwrap()],
        )
        .output()
        .unwrap();
    assert!(plot.status.success(), "{plot:?}");
    assert_eq!(body, std::fs::read_to_string(&out).unwrap());
    assert!(
        body.starts_with("<svg") && body.contains("X: following error"),
        "{body}"
    );
    // The cause cleared and the fault reset: no black box any more.
    let code = Injection::ClearDriveFault(0).code().unwrap();
    client
        .request(kerf_proto::ControlCommand::Inject { code })
        .unwrap();
    let (code, answer) = control(s.addr, Some(TOKEN), r#"{"command":"reset"}"#);
    assert_eq!(code, 200, "{answer}");
    status_until(s.addr, "idle after the reset", |st| st["state"] == "idle");
    assert_eq!(svg(s.addr).0, 404);
}

#[test]
fn stopping_kerf_serve_stops_its_running_job_and_says_how_it_ended() {
    let mut s = served("stop");
    let auth = format!("Authorization: Bearer {TOKEN}");
    let (code, text) = http(
        s.addr,
        "POST",
        "/api/v1/program?name=slow.ngc",
        &[&auth],
        b"G21 G90\nG1 X60 F600\nM2\n",
    );
    assert_eq!(code, 202, "{text}");
    status_until(s.addr, "the part moving", |st| {
        st["state"] == "running" && st["position"]["x"].as_f64().unwrap() > 1.0
    });
    s._serve.signal("TERM");
    let exit = s._serve.wait_within(MACHINE_PATIENCE);
    assert!(exit.success(), "kerf serve: {exit}");
    let said = read_text(&s._serve.stderr);
    assert!(
        said.contains("kerf serve: stopped job 1 (`slow.ngc`) at shutdown: exit "),
        "{said}"
    );
    // The program was aborted, not left running without its `kerf run`: the machine
    // stopped short of X60 and stays there.
    let deadline = Instant::now() + MACHINE_PATIENCE;
    let stopped = loop {
        let st = s.env.status();
        if st["state"] == "idle" {
            break st;
        }
        assert!(Instant::now() < deadline, "never idle: {st}");
        std::thread::sleep(Duration::from_millis(20));
    };
    let x = stopped["position"]["x"].as_f64().unwrap();
    assert!(x > 1.0 && x < 60.0, "{stopped}");
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(s.env.status()["position"]["x"], stopped["position"]["x"]);
}

#[test]
fn in_a_real_browser_the_page_runs_holds_and_resumes_the_example_part_a_second_tab_watches_and_a_closed_tab_stops_its_jog()
 {
    let s = served("browser");
    let mut b = Browser::start(&s.env.dir);
    let url = format!("http://{}/", s.addr);
    let (_, a) = b.open(&url);
    b.until(
        &a,
        "the idle machine",
        "document.getElementById('state').textContent === 'idle'",
    );
    b.until(
        &a,
        "the DRO",
        "document.querySelectorAll('#dro tbody tr').length === 3",
    );
    b.eval(
        &a,
        &format!("(() => {{ const t = document.getElementById('token'); t.value = '{TOKEN}'; t.dispatchEvent(new Event('change')); return true; }})()"),
    );
    // The example part, chosen in the file input and run with the page's Run button.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/examples/quickstart.ngc");
    let part = root.canonicalize().unwrap();
    let document =
        b.call(Some(&a), "DOM.getDocument", serde_json::json!({}))["root"]["nodeId"].clone();
    let input = b.call(
        Some(&a),
        "DOM.querySelector",
        serde_json::json!({"nodeId": document, "selector": "#program-file"}),
    )["nodeId"]
        .clone();
    b.call(
        Some(&a),
        "DOM.setFileInputFiles",
        serde_json::json!({"files": [part.to_str().unwrap()], "nodeId": input}),
    );
    b.eval(&a, "document.getElementById('run').click(), true");
    b.until(
        &a,
        "the part running",
        "document.getElementById('state').textContent === 'running'",
    );
    // A second tab watches the same run.
    let (watcher_target, w) = b.open(&url);
    b.until(
        &w,
        "the run in the second tab",
        "document.getElementById('state').textContent === 'running'",
    );
    // The toolpath and the tool on it, drawn; a screenshot of the page while it runs.
    b.until(
        &a,
        "the toolpath",
        "view.toolpath !== null && view.cut.length > 5",
    );
    assert!(
        pixels(&mut b, &a, [0x24, 0x57, 0xa6]) > 100,
        "no toolpath drawn"
    );
    assert!(pixels(&mut b, &a, [0x1a, 0x8f, 0x3c]) > 20, "no tool drawn");
    assert!(pixels(&mut b, &a, [0xc0, 0x39, 0x2b]) > 10, "no cut drawn");
    let shot = b.call(
        Some(&a),
        "Page.captureScreenshot",
        serde_json::json!({"format": "png"}),
    )["data"]
        .as_str()
        .unwrap()
        .to_owned();
    let png = s.env.dir.join("page-running.png");
    std::fs::write(&png, decode_base64(&shot)).unwrap();
    assert!(
        std::fs::read(&png).unwrap().starts_with(b"\x89PNG"),
        "{}",
        png.display()
    );
    // Hold and cycle start from the page; both tabs show it; the part ends finished.
    b.eval(
        &a,
        "document.querySelector('button[data-command=hold]').click(), true",
    );
    b.until(
        &a,
        "the hold",
        "document.getElementById('state').textContent === 'holding'",
    );
    b.until(
        &w,
        "the hold in the second tab",
        "document.getElementById('state').textContent === 'holding'",
    );
    b.eval(
        &a,
        "document.querySelector('button[data-command=resume]').click(), true",
    );
    b.until(
        &a,
        "the part finished",
        "document.getElementById('job').textContent.includes('finished (exit 0)')",
    );
    b.until(
        &w,
        "idle in the second tab",
        "document.getElementById('state').textContent === 'idle'",
    );
    // An MDI line typed in the first tab, which controls the machine since it ran the part.
    b.until(
        &a,
        "control in the first tab",
        "document.getElementById('lease').textContent === 'this tab'",
    );
    b.eval(
        &a,
        "(() => { const l = document.getElementById('mdi-line'); l.value = 'G0 X5 Y7'; l.dispatchEvent(new KeyboardEvent('keydown', { key: 'Enter' })); return true; })()",
    );
    b.until(
        &a,
        "the MDI line done",
        "document.getElementById('job').textContent === 'MDI G0 X5 Y7: finished (exit 0)'",
    );
    b.until(
        &a,
        "the DRO after the MDI line",
        "document.querySelector('#dro-x').cells[1].textContent === '5.000' && document.querySelector('#dro-y').cells[1].textContent === '7.000'",
    );
    // The part's toolpath, kept through the MDI line, and the cut (all of it now, drawn
    // over the toolpath) in the 3D view: another picture than the XY view's.
    let picture = "document.getElementById('view').toDataURL()";
    let xy = b.eval(&a, picture);
    b.eval(
        &a,
        "(() => { const p = document.getElementById('plane'); p.value = '3d'; p.dispatchEvent(new Event('change')); return true; })()",
    );
    assert!(
        pixels(&mut b, &a, [0xc0, 0x39, 0x2b]) > 100,
        "no cut drawn in 3D"
    );
    assert_ne!(b.eval(&a, picture), xy, "the 3D view is the XY view");
    let shot = b.call(
        Some(&a),
        "Page.captureScreenshot",
        serde_json::json!({"format": "png"}),
    )["data"]
        .as_str()
        .unwrap()
        .to_owned();
    std::fs::write(s.env.dir.join("page-3d.png"), decode_base64(&shot)).unwrap();
    // A button to home each axis.
    assert_eq!(
        b.eval(
            &a,
            "['x', 'y', 'z'].every((a) => document.querySelector(`#home button[data-axes=${a}]`) !== null)"
        ),
        true
    );
    // A continuous jog held in the second tab, then the tab closed while the button is
    // down: the renewals stop, and the daemon's dead man's switch stops the axis. The
    // second tab first takes control over from the first.
    b.eval(
        &w,
        &format!("(() => {{ const t = document.getElementById('token'); t.value = '{TOKEN}'; return true; }})()"),
    );
    b.until(
        &w,
        "the first tab's control shown in the second",
        "document.getElementById('lease').textContent.startsWith('another station') && document.getElementById('take').textContent === 'Take over'",
    );
    b.eval(&w, "document.getElementById('take').click(), true");
    b.until(
        &w,
        "control taken over",
        "document.getElementById('lease').textContent === 'this tab'",
    );
    b.until(
        &a,
        "control lost in the first tab",
        "document.getElementById('lease').textContent.startsWith('another station')",
    );
    let rect = b.eval(
        &w,
        "(() => { const r = document.querySelector('button[data-jog=\"x+\"]').getBoundingClientRect(); return [r.x + r.width / 2, r.y + r.height / 2]; })()",
    );
    let (x, y) = (rect[0].as_f64().unwrap(), rect[1].as_f64().unwrap());
    b.call(
        Some(&w),
        "Input.dispatchMouseEvent",
        serde_json::json!({"type": "mousePressed", "x": x, "y": y, "button": "left", "clickCount": 1}),
    );
    status_until(s.addr, "X jogging", |st| st["axes"]["x"]["jogging"] == true);
    b.call(
        None,
        "Target.closeTarget",
        serde_json::json!({"targetId": watcher_target}),
    );
    let closed_at = status_until(s.addr, "a status after the close", |_| true)["position"]["x"]
        .as_f64()
        .unwrap();
    let stopped = status_until(s.addr, "X stopped by the dead man's switch", |st| {
        st["axes"]["x"]["jogging"] == false && st["state"] == "idle"
    });
    // The bound from the configuration: the default jog speed over the dead-man time and
    // a renewal period, plus a generous stop (v²/a + v·√(v/j)).
    let config = kerf_config::Config::load(&s.env.config_path).unwrap();
    let x_axis = config.axes.x;
    let v = x_axis.velocity_mm_s * config.jog.default_speed_pct / 100.0;
    let bound = v * (f64::from(config.jog.deadman_ms) / 1000.0 + 0.05)
        + v * v / x_axis.acceleration_mm_s2
        + v * (v / x_axis.jerk_mm_s3).sqrt();
    let ran_on = stopped["position"]["x"].as_f64().unwrap() - closed_at;
    assert!(
        ran_on <= bound,
        "X ran {ran_on} mm after the tab closed (bound {bound})"
    );
    let still = status_until(s.addr, "a later status", |_| true);
    assert_eq!(
        still["position"]["x"], stopped["position"]["x"],
        "X moved again"
    );
}

/// CPU time (user + system) and peak resident memory of process `pid`, from /proc: s and
/// bytes.
fn cpu_and_peak_memory(pid: u32) -> (f64, u64) {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    // The fields after the command's closing parenthesis: utime and stime are the 12th
    // and 13th of them (fields 14 and 15 of the line), in clock ticks.
    let after = stat.rsplit_once(')').unwrap().1;
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks: u64 = fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap();
    let hz = 100.0; // USER_HZ, 100 on every Linux this runs on
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let kib: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap();
    (ticks as f64 / hz, kib * 1024)
}

#[test]
fn twenty_watchers_change_no_setpoint_and_kerf_serve_stays_within_its_memory_budget() {
    let s = served("load");
    status_until(s.addr, "idle", |st| st["state"] == "idle");
    // A part of lines and arcs without waits (no tool change, no spindle: the daemon
    // waits for those in real time, kerf sim does not), about 10 s; kerf sim's setpoints
    // for it, the machine at rest at 0.
    let mut text = String::from("G21 G90 G17\n");
    for i in 0..6 {
        let d = f64::from(i) * 2.0;
        text.push_str(&format!(
            "G1 X{} Y{d} F3000\nG1 X{} Y{d}\nG2 X{} Y{} I0 J10\nG1 X{} Y{} Z-1\nG3 X{} Y{d} I0 J-10\n",
            10.0 + d,
            60.0 - d,
            60.0 - d,
            d + 20.0,
            10.0 + d,
            d + 20.0,
            10.0 + d,
        ));
    }
    text.push_str("G0 Z5\nG0 X0 Y0\nG0 Z0\nM2\n");
    let part = s.env.write("load.ngc", &text);
    let sim = s.env.path("sim.csv");
    let out = s
        .env
        .kerf_command(
            &["sim"],
            &[part.to_str().unwrap(), "--out", sim.to_str().unwrap()],
        )
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "kerf sim: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // 20 watchers on the stream, each reading every message until the run is over.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let url = format!("ws://{}/api/v1/ws", s.addr);
    let watchers: Vec<_> = (0..20)
        .map(|_| {
            let (url, stop, addr) = (url.clone(), stop.clone(), s.addr);
            std::thread::spawn(move || {
                let connected = Instant::now();
                let stream = TcpStream::connect(addr).unwrap();
                stream.set_read_timeout(Some(MACHINE_PATIENCE)).unwrap();
                let mut ws = tungstenite::client(url.as_str(), stream).unwrap().0;
                let (mut messages, mut bytes) = (0u64, 0u64);
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    if let tungstenite::Message::Text(t) = ws.read().unwrap() {
                        messages += 1;
                        bytes += t.len() as u64;
                    }
                }
                (messages, bytes, connected.elapsed().as_secs_f64())
            })
        })
        .collect();
    let serve_pid = s._serve.pid();
    let (cpu0, _) = cpu_and_peak_memory(serve_pid);
    let started = Instant::now();
    let run = s.env.path("run.csv");
    s.env.kerf_ok(
        &["run"],
        &["--record", run.to_str().unwrap(), part.to_str().unwrap()],
    );
    let seconds = started.elapsed().as_secs_f64();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let counts: Vec<(u64, u64, f64)> = watchers.into_iter().map(|w| w.join().unwrap()).collect();
    let (cpu1, peak) = cpu_and_peak_memory(serve_pid);
    assert!(
        std::fs::read(&sim).unwrap() == std::fs::read(&run).unwrap(),
        "with 20 watchers the daemon's setpoints differ from kerf sim's"
    );
    for (messages, _, window) in &counts {
        assert!(*messages > 0, "a watcher received nothing: {counts:?}");
        // The server sends at most one every 50 ms: over the watcher's own window, at
        // most 20 a second and the first.
        assert!(
            *messages as f64 <= 20.0 * window + 1.0,
            "{messages} in {window} s"
        );
    }
    // The memory ceiling of deploy/kerf-serve.service is 256 MiB; it needs a small part.
    assert!(peak < 64 * 1024 * 1024, "kerf serve peaked at {peak} bytes");
    let per_watcher_bytes_s = counts.iter().map(|c| c.1).sum::<u64>() as f64 / 20.0 / seconds;
    eprintln!(
        "kerf serve with 20 watchers over a {seconds:.1} s run: CPU {:.1} % of one core, peak RSS {:.1} MiB, {:.1} kB/s per watcher",
        100.0 * (cpu1 - cpu0) / seconds,
        peak as f64 / 1048576.0,
        per_watcher_bytes_s / 1000.0
    );
}
