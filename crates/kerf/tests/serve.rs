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
#[path = "serve/load.rs"]
mod load;
#[path = "serve/page.rs"]
mod page;

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
    // Its lines, for its progress (counted here with the standard library's lines()).
    let lines = std::str::from_utf8(part).unwrap().lines().count();
    assert_eq!(answer["job"]["lines"], lines, "{answer}");
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
    // The job finished, then the status idle where `there` holds: kerf serve reads the
    // daemon's status every 50 ms, so a short line's job may end before the status
    // shows its motion (the test fails if it never gets there within the patience).
    let finished = |what: &str, there: &dyn Fn(&Value) -> bool| {
        let job = job_until(s.addr, what, |j| j["state"] != "running");
        assert_eq!(
            (job["state"].clone(), job["exit_code"].clone()),
            (Value::from("finished"), Value::from(0)),
            "{what}: {job}"
        );
        status_until(s.addr, what, |st| st["state"] == "idle" && there(st))
    };
    // A line goes where it says, in work coordinates.
    let (code, answer) = mdi("G0 X12.5 Y-3");
    assert_eq!(code, 202, "{answer}");
    assert_eq!(
        (answer["job"]["kind"].clone(), answer["job"]["name"].clone()),
        (Value::from("mdi"), Value::from("G0 X12.5 Y-3"))
    );
    finished("the first line at X12.5 Y-3", &|st| {
        (work(st, "x") - 12.5).abs() < 1e-9 && (work(st, "y") + 3.0).abs() < 1e-9
    });
    // Each line starts in a program's modal state (docs/API.md): the G91 of one line does
    // not carry into the next, which is absolute again.
    let (code, answer) = mdi("G91 G0 X1");
    assert_eq!(code, 202, "{answer}");
    finished("the incremental line at X13.5", &|st| {
        (work(st, "x") - 13.5).abs() < 1e-9
    });
    let (code, answer) = mdi("G0 X1");
    assert_eq!(code, 202, "{answer}");
    let at = finished("the absolute line at X1", &|st| {
        (work(st, "x") - 1.0).abs() < 1e-9
    });
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
        r#"{"line":"G0 X5\u0000"}"#.to_owned(),
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
    finished("the touch-off", &|_| true);
    // The parameter file keeps 6 decimals, as LinuxCNC's does: within 0.5e-6 mm.
    let touched = status_until(s.addr, "X reading 0 in G54", |st| {
        st["dro"]["work"]["x"]
            .as_f64()
            .is_some_and(|x| x.abs() <= 0.5e-6)
    });
    assert_eq!(touched["position"]["x"], stopped["position"]["x"]);
    let offset = touched["dro"]["work_offset"]["x"].as_f64().unwrap();
    let machine_x = stopped["position"]["x"].as_f64().unwrap();
    assert!((offset - machine_x).abs() <= 0.5e-6, "{touched}");
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
