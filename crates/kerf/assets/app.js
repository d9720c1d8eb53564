// Kerf's web page: the status from the WebSocket (/api/v1/ws, 20 Hz at most), control
// through POST /api/v1/control with the token of this tab (docs/API.md).
"use strict";

const AXES = ["x", "y", "z", "a", "b", "c"];
const $ = (id) => document.getElementById(id);
let latest = null;

// The token stays in this tab's session storage only.
$("token").value = sessionStorage.getItem("kerf-token") || "";
$("token").addEventListener("change", () => sessionStorage.setItem("kerf-token", $("token").value));

async function control(body) {
  const response = await fetch("/api/v1/control", {
    method: "POST",
    headers: { "Content-Type": "application/json", "Authorization": "Bearer " + $("token").value },
    body: JSON.stringify(body),
  });
  const answer = await response.json();
  $("answer").textContent = answer.ok ? "done: " + body.command : "refused: " + answer.error.message;
  return answer;
}

// A program from this computer: sent as the body of POST /api/v1/program and run by the
// machine's `kerf run`; the job's state and what it said come from GET /api/v1/job.
$("run").addEventListener("click", async () => {
  const file = $("program-file").files[0];
  if (!file) { $("answer").textContent = "choose a program file first"; return; }
  const response = await fetch("/api/v1/program?name=" + encodeURIComponent(file.name.replace(/[^A-Za-z0-9._-]/g, "_")), {
    method: "POST",
    headers: { "Authorization": "Bearer " + $("token").value },
    body: await file.arrayBuffer(),
  });
  const answer = await response.json();
  $("answer").textContent = answer.ok ? "started: " + file.name : "refused: " + answer.error.message;
  showJob();
});

// The toolpath view: the job's toolpath (GET /api/v1/job/toolpath, machine mm), the part
// already cut (the tool's positions from the stream while a program runs) and the tool.
const view = { toolpath: null, jobId: null, cut: [], tool: null };
const PLANES = { xy: [0, 1], xz: [0, 2], yz: [1, 2] };

function draw() {
  const canvas = $("view");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const [u, v] = PLANES[$("plane").value];
  const all = [];
  if (view.toolpath) for (const p of view.toolpath.paths) all.push(...p.points);
  all.push(...view.cut);
  if (view.tool) all.push(view.tool);
  if (all.length === 0) return;
  let [u0, u1, v0, v1] = [Infinity, -Infinity, Infinity, -Infinity];
  for (const p of all) { u0 = Math.min(u0, p[u]); u1 = Math.max(u1, p[u]); v0 = Math.min(v0, p[v]); v1 = Math.max(v1, p[v]); }
  const margin = 20;
  const scale = Math.min((canvas.width - 2 * margin) / Math.max(u1 - u0, 1), (canvas.height - 2 * margin) / Math.max(v1 - v0, 1));
  const at = (p) => [margin + (p[u] - u0) * scale, canvas.height - margin - (p[v] - v0) * scale];
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

async function showJob() {
  const answer = await (await fetch("/api/v1/job")).json();
  const job = answer.job;
  if (job && job.id !== view.jobId) {
    const response = await fetch("/api/v1/job/toolpath");
    if (response.ok) {
      view.toolpath = await response.json();
      view.jobId = job.id;
      view.cut = [];
      draw();
    }
  }
  $("job").textContent = job ? job.name + ": " + job.state + (job.exit_code === null ? "" : " (exit " + job.exit_code + ")") : "none";
  $("job-messages").textContent = job ? job.messages.join("\n") : "";
}
setInterval(showJob, 1000);
showJob();

for (const b of document.querySelectorAll("button[data-command]")) {
  b.addEventListener("click", () => {
    const body = { command: b.dataset.command };
    if (b.dataset.axes) body.axes = b.dataset.axes;
    control(body);
  });
}
for (const [id, command] of [["override", "override"], ["spindle-override", "spindle_override"]]) {
  $(id).addEventListener("change", () => control({ command, percent: Number($(id).value) }));
}

// Continuous jog: renewed every 50 ms while the button is held; released, or the tab
// closed, the renewals stop and the daemon's dead man's switch stops the axis.
function jogButton(axis, direction) {
  const b = document.createElement("button");
  b.textContent = axis.toUpperCase() + direction;
  b.dataset.jog = axis + direction;
  let timer = null;
  const stop = () => {
    if (timer === null) return;
    clearInterval(timer);
    timer = null;
    control({ command: "jog_stop", axis });
  };
  b.addEventListener("pointerdown", () => {
    if (timer !== null) return;
    const renew = () => control({ command: "jog", axis, direction });
    renew();
    timer = setInterval(renew, 50);
  });
  b.addEventListener("pointerup", stop);
  b.addEventListener("pointerleave", stop);
  return b;
}

function fixed(v) { return typeof v === "number" ? v.toFixed(3) : "–"; }

function show(message) {
  latest = message;
  if (!message.connected) {
    $("state").textContent = "no daemon";
    $("state").className = "state fault";
    $("fault").textContent = message.reason || "";
    return;
  }
  const s = message.status;
  $("machine").textContent = s.machine;
  $("state").textContent = s.state;
  $("state").className = "state " + s.state;
  $("line").textContent = s.line;
  $("queued").textContent = (s.queued_s || 0).toFixed(1);
  $("pause").textContent = s.pause ? "paused: " + (s.pause.reason || "") : "";
  $("fault").textContent = s.fault || "";
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
    for (const a of present) {
      const row = body.insertRow();
      row.id = "dro-" + a;
      for (let i = 0; i < 4; i++) row.insertCell();
      row.cells[0].textContent = a.toUpperCase();
      $("jog").append(jogButton(a, "-"), jogButton(a, "+"));
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
