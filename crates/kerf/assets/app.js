// Kerf's web page: the status from the WebSocket (/api/v1/ws, 20 Hz at most), control
// through POST /api/v1/control with the token of this tab and its id for the control
// lease (docs/API.md).
"use strict";

const AXES = ["x", "y", "z", "a", "b", "c"];
const $ = (id) => document.getElementById(id);
let latest = null;

// The token stays in this tab's session storage only.
$("token").value = sessionStorage.getItem("kerf-token") || "";
$("token").addEventListener("change", () => sessionStorage.setItem("kerf-token", $("token").value));

// This tab's id for the control lease: random, kept over a reload of the tab.
const CLIENT = sessionStorage.getItem("kerf-client") || ("page-" + Array.from(crypto.getRandomValues(new Uint8Array(12)), (b) => b.toString(16).padStart(2, "0")).join(""));
sessionStorage.setItem("kerf-client", CLIENT);
const headers = (json) => {
  const h = { "Authorization": "Bearer " + $("token").value, "Kerf-Client": CLIENT };
  if (json) h["Content-Type"] = "application/json";
  return h;
};

// The control lease: who controls (GET /api/v1/control/lease every second), taken with a
// tab's first command or the Take control button, renewed every 3 s while this tab holds
// it, released with Release or by closing the tab (it lapses).
let lease = null;
async function showLease() {
  const answer = await (await fetch("/api/v1/control/lease", { headers: { "Kerf-Client": CLIENT } })).json();
  lease = answer.lease;
  $("lease").textContent = lease === null ? "nobody" : lease.yours ? "this tab" : "another station (" + lease.peer + ")";
  $("take").textContent = lease !== null && !lease.yours ? "Take over" : "Take control";
}
async function leaseRequest(action, force) {
  const response = await fetch("/api/v1/control/lease", { method: "POST", headers: headers(true), body: JSON.stringify({ action, force }) });
  const answer = await response.json();
  if (!answer.ok) $("answer").textContent = "refused: " + answer.error.message;
  await showLease();
  return answer.ok;
}
$("take").addEventListener("click", () => leaseRequest("take", lease !== null && !lease.yours));
$("release").addEventListener("click", () => leaseRequest("release", false));
setInterval(() => { if (lease !== null && lease.yours) leaseRequest("take", false); else showLease(); }, 3000);
setInterval(showLease, 1000);
showLease();

// Stopping is everyone's; anything else takes the lease first when nobody holds it.
const STOPS = ["hold", "abort", "jog_stop"];
async function mayControl(command) {
  if (STOPS.includes(command) || (lease !== null && lease.yours)) return true;
  if (lease !== null) { $("answer").textContent = "refused: another station controls the machine (Take over to control it from here)"; return false; }
  return leaseRequest("take", false);
}

async function control(body) {
  if (!(await mayControl(body.command))) return null;
  const response = await fetch("/api/v1/control", { method: "POST", headers: headers(true), body: JSON.stringify(body) });
  const answer = await response.json();
  $("answer").textContent = answer.ok ? "done: " + body.command : "refused: " + answer.error.message;
  return answer;
}

// A program from this computer: sent as the body of POST /api/v1/program and run by the
// machine's `kerf run`; the job's state and what it said come from GET /api/v1/job.
$("run").addEventListener("click", async () => {
  const file = $("program-file").files[0];
  if (!file) { $("answer").textContent = "choose a program file first"; return; }
  if (!(await mayControl("run"))) return;
  const response = await fetch("/api/v1/program?name=" + encodeURIComponent(file.name.replace(/[^A-Za-z0-9._-]/g, "_")), {
    method: "POST",
    headers: headers(false),
    body: await file.arrayBuffer(),
  });
  const answer = await response.json();
  $("answer").textContent = answer.ok ? "started: " + file.name : "refused: " + answer.error.message;
  showJob();
});

// An MDI line: POST /api/v1/mdi, run by the machine's `kerf mdi LINE` (a job, shown as
// the program's are).
async function runMdi() {
  const line = $("mdi-line").value.trim();
  if (line === "" || !(await mayControl("mdi"))) return;
  const response = await fetch("/api/v1/mdi", { method: "POST", headers: headers(true), body: JSON.stringify({ line }) });
  const answer = await response.json();
  $("answer").textContent = answer.ok ? "MDI: " + line : "refused: " + answer.error.message;
  showJob();
}
$("mdi-run").addEventListener("click", runMdi);
$("mdi-line").addEventListener("keydown", (e) => { if (e.key === "Enter") runMdi(); });

// The toolpath view: the job's toolpath (GET /api/v1/job/toolpath, machine mm), the part
// already cut (the tool's positions from the stream while a program runs) and the tool;
// in a plane, or in 3D (an orthographic view turned by dragging).
const view = { toolpath: null, jobId: null, job: null, cut: [], tool: null, yaw: -0.6, pitch: 0.9 };
const PLANES = { xy: [0, 1], xz: [0, 2], yz: [1, 2] };

// The projection of a point (machine mm) on the view's plane: [u, v].
function projection() {
  const plane = $("plane").value;
  if (plane !== "3d") {
    const [u, v] = PLANES[plane];
    return (p) => [p[u], p[v]];
  }
  // Turned about Z by the yaw, then tilted about the screen's horizontal by the pitch.
  const [cy, sy, cp, sp] = [Math.cos(view.yaw), Math.sin(view.yaw), Math.cos(view.pitch), Math.sin(view.pitch)];
  return (p) => {
    const x = cy * p[0] - sy * p[1];
    const y = sy * p[0] + cy * p[1];
    return [x, cp * p[2] + sp * y];
  };
}

function draw() {
  const canvas = $("view");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const project = projection();
  canvas.className = $("plane").value === "3d" ? "orbit" : "";
  $("view-hint").textContent = $("plane").value === "3d" ? "(drag to turn)" : "";
  const all = [];
  if (view.toolpath) for (const p of view.toolpath.paths) all.push(...p.points);
  all.push(...view.cut);
  if (view.tool) all.push(view.tool);
  if (all.length === 0) return;
  let [u0, u1, v0, v1] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const p of all) { const [pu, pv] = project(p); u0 = Math.min(u0, pu); u1 = Math.max(u1, pu); v0 = Math.min(v0, pv); v1 = Math.max(v1, pv); }
  const margin = 20;
  const scale = Math.min((canvas.width - 2 * margin) / Math.max(u1 - u0, 1), (canvas.height - 2 * margin) / Math.max(v1 - v0, 1));
  const at = (p) => { const [pu, pv] = project(p); return [margin + (pu - u0) * scale, canvas.height - margin - (pv - v0) * scale]; };
  const line = (points, style, dash) => {
    if (points.length < 2) return;
    ctx.strokeStyle = style; ctx.setLineDash(dash); ctx.beginPath();
    points.forEach((p, i) => { const [x, y] = at(p); if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y); });
    ctx.stroke();
  };
  ctx.lineWidth = 1;
  if (view.toolpath) for (const p of view.toolpath.paths) line(p.points, p.rapid ? "#999" : "#2457a6", p.rapid ? [4, 4] : []);
  ctx.lineWidth = 2.5;
  line(view.cut, "#c0392b", []);
  if (view.tool) {
    const [x, y] = at(view.tool);
    ctx.setLineDash([]); ctx.fillStyle = "#1a8f3c"; ctx.beginPath(); ctx.arc(x, y, 6, 0, 2 * Math.PI); ctx.fill();
  }
}
$("plane").addEventListener("change", draw);
{
  let drag = null;
  $("view").addEventListener("pointerdown", (e) => { if ($("plane").value === "3d") drag = [e.clientX, e.clientY]; });
  $("view").addEventListener("pointermove", (e) => {
    if (drag === null) return;
    view.yaw += (e.clientX - drag[0]) * 0.01;
    view.pitch = Math.max(0, Math.min(Math.PI / 2, view.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    draw();
  });
  for (const end of ["pointerup", "pointerleave"]) $("view").addEventListener(end, () => { drag = null; });
}

async function showJob() {
  const answer = await (await fetch("/api/v1/job")).json();
  const job = answer.job;
  view.job = job;
  if (job && job.kind === "program" && job.id !== view.jobId) {
    const response = await fetch("/api/v1/job/toolpath");
    if (response.ok) {
      view.toolpath = await response.json();
      view.jobId = job.id;
      view.cut = [];
      draw();
    }
  }
  $("job").textContent = job ? (job.kind === "mdi" ? "MDI " : "") + job.name + ": " + job.state + (job.exit_code === null ? "" : " (exit " + job.exit_code + ")") : "none";
  $("job-messages").textContent = job ? job.messages.join("\n") : "";
}
setInterval(showJob, 1000);
showJob();

function commandButton(b) {
  b.addEventListener("click", () => {
    const body = { command: b.dataset.command };
    if (b.dataset.axes) body.axes = b.dataset.axes;
    control(body);
  });
}
for (const b of document.querySelectorAll("button[data-command]")) commandButton(b);
for (const [id, command] of [["override", "override"], ["spindle-override", "spindle_override"]]) {
  $(id).addEventListener("change", () => control({ command, percent: Number($(id).value) }));
}

// Continuous jog: renewed every 50 ms while the button is held; released, or the tab
// closed, the renewals stop and the daemon's dead man's switch stops the axis. With a step
// chosen, a press moves the axis by the step.
function jogButton(axis, direction) {
  const b = document.createElement("button");
  b.textContent = axis.toUpperCase() + direction;
  b.dataset.jog = axis + direction;
  let timer = null;
  let held = false;
  b.addEventListener("click", () => {
    const step = Number($("jog-step").value);
    if (step > 0) control({ command: "jog_step", axis, distance: direction === "+" ? step : -step });
  });
  const stop = () => {
    held = false;
    if (timer === null) return;
    clearInterval(timer);
    timer = null;
    control({ command: "jog_stop", axis });
  };
  b.addEventListener("pointerdown", async () => {
    if (timer !== null || Number($("jog-step").value) > 0) return;
    held = true;
    // Released while control was being taken: no jog.
    if (!(await mayControl("jog")) || !held || timer !== null) return;
    const renew = () => control({ command: "jog", axis, direction });
    renew();
    timer = setInterval(renew, 50);
  });
  b.addEventListener("pointerup", stop);
  b.addEventListener("pointerleave", stop);
  return b;
}

function fixed(v) { return typeof v === "number" ? v.toFixed(3) : "–"; }

let previous = null;
function show(message) {
  latest = message;
  if (!message.connected) {
    $("state").textContent = "no daemon";
    $("state").className = "state fault";
    $("fault").textContent = message.reason || "";
    previous = message;
    return;
  }
  const s = message.status;
  $("machine").textContent = s.machine;
  $("state").textContent = s.state;
  $("state").className = "state " + s.state;
  // The program's progress: the line being executed of its lines (GET /api/v1/job).
  const lines = view.job && view.job.kind === "program" ? view.job.lines : 0;
  $("line").textContent = lines > 0 ? s.line + " of " + lines + " (" + Math.min(100, Math.round(100 * s.line / lines)) + " %)" : s.line;
  // The path speed, from the positions of this message and the last (about 50 ms apart).
  if (previous && previous.connected && message.t_ms > previous.t_ms) {
    const p0 = previous.status.position, p1 = s.position;
    const mm = Math.hypot(p1.x - p0.x, p1.y - p0.y, p1.z - p0.z);
    $("feed").textContent = Math.round(mm / (message.t_ms - previous.t_ms) * 60000);
  }
  previous = message;
  $("queued").textContent = (s.queued_s || 0).toFixed(1);
  $("pause").textContent = s.pause ? "paused: " + (s.pause.reason || "") : "";
  $("fault").textContent = s.fault || "";
  // The black box the daemon wrote at its fault, drawn, until the reset clears it.
  const dump = s.safety && s.safety.dump;
  $("blackbox-figure").hidden = !dump;
  if (dump && $("blackbox").dataset.dump !== dump) {
    $("blackbox").dataset.dump = dump;
    $("blackbox").src = "/api/v1/fault/blackbox.svg?dump=" + encodeURIComponent(dump);
  }
  $("override-value").textContent = s.override_pct;
  if (document.activeElement !== $("override")) $("override").value = s.override_pct;
  if (s.spindle) {
    $("spindle-override-value").textContent = s.spindle.override_pct;
    if (document.activeElement !== $("spindle-override")) $("spindle-override").value = s.spindle.override_pct;
    $("spindle").textContent = "spindle " + Math.round(s.spindle.actual_rpm) + " rpm";
  }
  const body = $("dro").tBodies[0];
  const present = AXES.filter((a) => a in s.position);
  if (body.rows.length !== present.length) {
    body.innerHTML = "";
    $("jog").innerHTML = "";
    for (const b of $("home").querySelectorAll("button[data-axes]:not([data-axes=all])")) b.remove();
    for (const a of present) {
      const row = body.insertRow();
      row.id = "dro-" + a;
      for (let i = 0; i < 4; i++) row.insertCell();
      row.cells[0].textContent = a.toUpperCase();
      $("jog").append(jogButton(a, "-"), jogButton(a, "+"));
      const home = document.createElement("button");
      home.textContent = "Home " + a.toUpperCase();
      home.dataset.command = "home";
      home.dataset.axes = a;
      commandButton(home);
      $("home").append(home);
    }
  }
  for (const a of present) {
    const row = $("dro-" + a);
    row.cells[1].textContent = s.dro ? fixed(s.dro.work[a]) : "–";
    row.cells[2].textContent = fixed(s.position[a]);
    row.cells[3].textContent = s.axes && s.axes[a] && s.axes[a].homed ? "yes" : "no";
  }
  $("system").textContent = s.dro ? s.dro.system + ", tool " + s.dro.tool : "";
  const p = s.position;
  view.tool = [p.x, p.y, p.z];
  if (s.state === "running" || s.state === "holding" || s.state === "paused") {
    const last = view.cut[view.cut.length - 1];
    if (!last || last[0] !== p.x || last[1] !== p.y || last[2] !== p.z) {
      view.cut.push(view.tool);
      if (view.cut.length > 20000) view.cut.shift();
    }
  }
  draw();
}

function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/api/v1/ws");
  ws.onmessage = (event) => show(JSON.parse(event.data));
  ws.onclose = () => {
    $("state").textContent = "connecting…";
    setTimeout(connect, 1000);
  };
}
connect();
