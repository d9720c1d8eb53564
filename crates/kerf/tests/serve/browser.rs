//! Headless Chromium driven through its DevTools protocol, for `kerf serve`'s page.

use std::net::TcpStream;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common::{MACHINE_PATIENCE, Proc, read_text};
use crate::json;

/// Headless Chromium (Debian's `chromium`) driven through its DevTools protocol over a
/// WebSocket: one browser, pages opened and closed as tabs.
pub struct Browser {
    ws: tungstenite::WebSocket<TcpStream>,
    next_id: u64,
    _process: Proc,
}

impl Browser {
    /// Starts `chromium --headless` with a profile of its own in `dir`. Fails, saying so,
    /// where Chromium is not installed (`.ci/run` installs it).
    pub fn start(dir: &std::path::Path) -> Browser {
        let chromium = ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
            .into_iter()
            .find(|p| std::path::Path::new(p).is_file())
            .expect("Chromium is not installed: `apt-get install chromium` (.ci/run does)");
        let profile = dir.join("chromium-profile");
        let mut c = std::process::Command::new(chromium);
        c.args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--remote-debugging-port=0",
            "--window-size=1280,1000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("about:blank");
        let process = Proc::start("chromium", dir, c);
        let deadline = Instant::now() + MACHINE_PATIENCE;
        let url = loop {
            let said = read_text(&process.stderr);
            if let Some(rest) = said.split("DevTools listening on ").nth(1) {
                break rest.lines().next().unwrap().trim().to_owned();
            }
            assert!(Instant::now() < deadline, "Chromium never listened: {said}");
            std::thread::sleep(Duration::from_millis(50));
        };
        let host = url
            .trim_start_matches("ws://")
            .split('/')
            .next()
            .unwrap()
            .to_owned();
        let stream = TcpStream::connect(&host).unwrap();
        stream.set_read_timeout(Some(MACHINE_PATIENCE)).unwrap();
        let (ws, _) = tungstenite::client(url.as_str(), stream).expect("the DevTools socket");
        Browser {
            ws,
            next_id: 1,
            _process: process,
        }
    }

    /// Calls `method` (in the tab of `session`, or on the browser) and returns its result.
    pub fn call(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        let mut msg = serde_json::json!({"id": id, "method": method, "params": params});
        if let Some(s) = session {
            msg["sessionId"] = Value::from(s);
        }
        self.ws
            .send(tungstenite::Message::Text(msg.to_string().into()))
            .unwrap();
        loop {
            let m = match self.ws.read().expect("a DevTools message") {
                tungstenite::Message::Text(t) => json(t.as_str()),
                _ => continue,
            };
            if m["id"] == id {
                assert!(m["error"].is_null(), "{method}: {m}");
                return m["result"].clone();
            }
        }
    }

    /// Opens `url` in a new tab: its target and session.
    pub fn open(&mut self, url: &str) -> (String, String) {
        let target =
            self.call(None, "Target.createTarget", serde_json::json!({"url": url}))["targetId"]
                .as_str()
                .unwrap()
                .to_owned();
        let session = self.call(
            None,
            "Target.attachToTarget",
            serde_json::json!({"targetId": target, "flatten": true}),
        )["sessionId"]
            .as_str()
            .unwrap()
            .to_owned();
        (target, session)
    }

    /// The value of JavaScript `expression` in the tab of `session` (promises awaited).
    pub fn eval(&mut self, session: &str, expression: &str) -> Value {
        let r = self.call(
            Some(session),
            "Runtime.evaluate",
            serde_json::json!({"expression": expression, "returnByValue": true, "awaitPromise": true}),
        );
        assert!(r["exceptionDetails"].is_null(), "{expression}: {r}");
        r["result"]["value"].clone()
    }

    /// A PNG screenshot of the tab of `session`, written to `path`.
    pub fn screenshot(&mut self, session: &str, path: &std::path::Path) {
        let shot = self.call(
            Some(session),
            "Page.captureScreenshot",
            serde_json::json!({"format": "png"}),
        )["data"]
            .as_str()
            .unwrap()
            .to_owned();
        std::fs::write(path, decode_base64(&shot)).unwrap();
    }

    /// Waits until `expression` is true in the tab of `session` (an exception, as while
    /// the page still loads, counts as not yet).
    pub fn until(&mut self, session: &str, what: &str, expression: &str) {
        let deadline = Instant::now() + MACHINE_PATIENCE;
        loop {
            let r = self.call(
                Some(session),
                "Runtime.evaluate",
                serde_json::json!({"expression": expression, "returnByValue": true}),
            );
            if r["exceptionDetails"].is_null() && r["result"]["value"] == true {
                return;
            }
            if Instant::now() >= deadline {
                // What the page shows instead, for the failure's message.
                let shown = self.call(
                    Some(session),
                    "Runtime.evaluate",
                    serde_json::json!({
                        "expression": "(async () => ['state', 'answer', 'job', 'line', 'lease', 'override-value'].map((id) => { const e = document.getElementById(id); return id + ': ' + (e ? e.textContent : '-'); }).join('; ') + '; the last message of the status stream: ' + JSON.stringify(latest) + '; GET /api/v1/status now: ' + await (await fetch('/api/v1/status')).text())()",
                        "returnByValue": true,
                        "awaitPromise": true
                    }),
                );
                panic!(
                    "the page never showed {what}: {r}; it shows {}",
                    shown["result"]["value"]
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// How many pixels of the view canvas have (about) colour `rgb`.
pub fn pixels(browser: &mut Browser, session: &str, rgb: [u8; 3]) -> u64 {
    browser
        .eval(session, &pixels_expression(rgb))
        .as_u64()
        .unwrap()
}

/// The JavaScript expression that counts the view canvas's pixels of (about) colour `rgb`.
pub fn pixels_expression(rgb: [u8; 3]) -> String {
    format!(
        "(() => {{ const c = document.getElementById('view'); \
         const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; \
         let n = 0; for (let i = 0; i < d.length; i += 4) {{ \
         if (Math.abs(d[i] - {}) < 40 && Math.abs(d[i+1] - {}) < 40 && Math.abs(d[i+2] - {}) < 40 && d[i+3] > 200) n++; }} \
         return n; }})()",
        rgb[0], rgb[1], rgb[2]
    )
}

/// Standard base64 (the screenshot), decoded.
fn decode_base64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let bytes: Vec<u8> = text.bytes().filter(|c| *c != b'=').collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let v: Vec<u32> = chunk.iter().map(|c| u32::from(value(*c))).collect();
        let n = v.iter().fold(0u32, |acc, x| (acc << 6) | x) << (6 * (4 - v.len()));
        let take = v.len() * 6 / 8;
        out.extend_from_slice(&n.to_be_bytes()[1..1 + take]);
    }
    out
}
