//! The page in a real browser (headless Chromium): the example part run, held and resumed,
//! a second tab watching, the toolpath in 2D and 3D, an MDI line, control taken over, and
//! a closed tab's jog stopped by the daemon's dead man's switch.

use crate::browser::{Browser, pixels, pixels_expression};
use crate::{TOKEN, served, status_until};

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
    // Its progress: the line being executed of the part's lines.
    let lines = std::fs::read_to_string(&part).unwrap().lines().count();
    b.until(
        &a,
        "the progress",
        &format!(
            "/^\\d+ of {lines} \\(\\d+ %\\)$/.test(document.getElementById('line').textContent)"
        ),
    );
    // The feed override slowed to 20 % from the page's slider, so that the part cannot end
    // before the hold below, however loaded the machine running the test is.
    set_feed_override(&mut b, &a, 20);
    // A second tab watches the same run.
    let (watcher_target, w) = b.open(&url);
    b.until(
        &w,
        "the run in the second tab",
        "document.getElementById('state').textContent === 'running'",
    );
    // The toolpath and the tool on it, drawn; a screenshot of the page while it runs.
    // The cut is waited for until it shows in XY: its first points may be plunges along Z,
    // which the XY view draws as a dot.
    b.until(
        &a,
        "the toolpath and the cut in XY",
        &format!(
            "view.toolpath !== null && view.cut.length > 5 && {} > 10",
            pixels_expression([0xc0, 0x39, 0x2b])
        ),
    );
    assert!(
        pixels(&mut b, &a, [0x24, 0x57, 0xa6]) > 100,
        "no toolpath drawn"
    );
    assert!(pixels(&mut b, &a, [0x1a, 0x8f, 0x3c]) > 20, "no tool drawn");
    assert!(pixels(&mut b, &a, [0xc0, 0x39, 0x2b]) > 10, "no cut drawn");
    let png = s.env.dir.join("page-running.png");
    b.screenshot(&a, &png);
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
    set_feed_override(&mut b, &a, 100);
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
    b.screenshot(&a, &s.env.dir.join("page-3d.png"));
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

/// Sets the feed override with the page's slider (as a user dragging it does: a value, then
/// `change`) and waits until the daemon's status shows it.
fn set_feed_override(b: &mut Browser, tab: &str, percent: u32) {
    b.eval(
        tab,
        &format!("(() => {{ const o = document.getElementById('override'); o.value = '{percent}'; o.dispatchEvent(new Event('change')); return true; }})()"),
    );
    b.until(
        tab,
        "the feed override",
        &format!("document.getElementById('override-value').textContent === '{percent}'"),
    );
}
