// rig console: the live rig over one WebSocket, and the run browser over plain HTTP.
// No build step: plain browser JavaScript and the vendored uPlot (static/vendor, MIT).
"use strict";

const $ = (id) => document.getElementById(id);
const COMPONENTS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"];
const COLORS = ["#d62728", "#2ca02c", "#1f77b4", "#ff7f0e", "#9467bd", "#8c564b"];
const PHASE_COLORS = ["#1f77b433", "#2ca02c33", "#ff7f0e33", "#9467bd33", "#8c564b33", "#e377c233", "#7f7f7f33"];
const HISTORY_S = 60;

// What tests and the benchmark read: the page's own view of the rig.
const state = {
  frames: 0, frameIndex: -1, frameT: null, wrench: null, axes: {}, control: null, events: [], run: null,
  flow: null, flows: 0, runFlow: null, progress: [], progressPolls: 0, rig: null,
  progressEveryMs: 1000,  // how often the progress panel asks (a test may ask more often)
};
window.rigConsole = state;

// A number for a legend or a tick: never "-0.000".
function fixed(v, digits) {
  const r = Number(v).toFixed(digits);
  return /^-0\.?0*$/.test(r) ? r.slice(1) : r;
}

// A run's status with its reason, never the status twice ("interrupted (interrupted (SIGINT)…"), as
// common/wording.py's status_text says it on the command line.
function statusText(status, reason) {
  reason = (reason || "").trim();
  if (!reason) return status;
  if (reason.toLowerCase().startsWith(status.toLowerCase())) {
    let rest = reason.slice(status.length).trim();
    if (rest.startsWith("(") && rest.includes(")")) {
      const close = rest.indexOf(")");
      rest = rest.slice(1, close) + rest.slice(close + 1);
    }
    rest = rest.replace(/^[:;, ]+/, "").trim();
    return rest ? `${status} (${rest})` : status;
  }
  return `${status} (${reason})`;
}

// The newest value of series si (what the legend shows while the cursor is off the chart).
function newest(u, si) {
  const data = u.data[si] || [];
  for (let k = data.length - 1; k >= 0; k--) if (data[k] != null) return data[k];
  return null;
}

// A chart whose legend names each series with its unit and shows its value: at the cursor, else at
// frame at() (the run browser's slider) or the newest one; every axis has ticks, labelled with its unit.
// The least span of a chart's y axis, per unit: a gauge's noise (about 1 N·mm on Mz at rest) drawn over a
// span of a few N·mm zigzagged the whole height and read as a solid bar; over these spans it reads as a line.
const MIN_SPAN = { "N": 1, "N·mm": 20 };

function yRange(minSpan) {
  return (u, min, max) => {
    if (min == null || max == null || !isFinite(min) || !isFinite(max)) return [-minSpan / 2, minSpan / 2];
    const span = Math.max(max - min, minSpan), mid = (max + min) / 2, pad = 0.05 * span;
    return [mid - span / 2 - pad, mid + span / 2 + pad];
  };
}

// A chart as wide as its box, now and whenever the window is resized (a chart laid out wider than an
// 800 px window was cut off at its right, x stopping at 52 of 86 s).
function chartWidth(target) { return Math.max(280, Math.floor(target.clientWidth || 480)); }

function chart(target, labels, units, colors, hooks, xRange, xLabel, at) {
  const width = chartWidth(target);
  const unitOf = (i) => (Array.isArray(units) ? units[i] : units);
  const series = [{
    label: xLabel || "t (s)",
    value: (u, v, si, idx) => {
      if (idx != null) return fixed(v, 2);
      if (at && at() != null && u.data[0][at()] != null) return fixed(u.data[0][at()], 2);
      return xRange ? "now" : "last";
    },
  }].concat(labels.map((label, i) => ({
    label: `${label} (${unitOf(i)})`, stroke: colors[i], width: 1.5,
    value: (u, v, si, idx) => {
      const w = idx != null ? v : at && at() != null ? (u.data[si] || [])[at()] : newest(u, si);
      return w == null ? "–" : fixed(w, 3);
    },
  })));
  const yLabel = Array.isArray(units) ? Array.from(new Set(units)).join(", ") : units;
  const ticks = (u, splits) => splits.map((v) => (v == null ? "" : fixed(v, Math.abs(v) < 10 ? 2 : 1).replace(/\.?0+$/, "") || "0"));
  const u = new uPlot(
    {
      width, height: 210, series, hooks: hooks || {},
      scales: {
        x: xRange ? { time: false, range: () => xRange } : { time: false },
        y: MIN_SPAN[yLabel] ? { range: yRange(MIN_SPAN[yLabel]) } : {},
      },
      padding: [hooks && hooks.drawClear ? 18 : 8, 8, 0, 0],  // the phase names' strip above the plot
      axes: [{ label: xLabel || "s", space: 40 }, { label: yLabel, size: 60, space: 20, values: ticks }],
      legend: { live: true },
    },
    [[]].concat(labels.map(() => [])),
    target,
  );
  charts.push({ u, target });
  return u;
}

const charts = [];
window.addEventListener("resize", () => {
  for (const c of charts) {
    const w = chartWidth(c.target);
    if (c.target.isConnected && w !== c.u.width) c.u.setSize({ width: w, height: c.u.height });
  }
});

// New data, and the legend's values with it while the cursor is off the chart.
function setChartData(u, data) {
  u.setData(data);
  if (u.cursor.idx == null) u.setLegend({ idx: null });
}

// ---- the live rig -------------------------------------------------------------------------
const live = { ws: null, ref: null, wrench: [], forces: null, moments: null, limits: null, draws: [], flowScale: 5, linked: false };
const UNITS = ["N", "N", "N", "N·mm", "N·mm", "N·mm"];

function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
  ws.binaryType = "arraybuffer";
  live.ws = ws;
  ws.onopen = () => { live.linked = true; showLink(); };
  ws.onclose = () => {
    live.linked = false;
    setPill($("link-status"), "disconnected: reload the page", "bad"); setControl(null);
  };
  ws.onmessage = (event) => {
    if (event.data instanceof ArrayBuffer) drawFrame(event.data);
    else onMessage(JSON.parse(event.data));
  };
}

function send(message) {
  if (live.ws && live.ws.readyState === WebSocket.OPEN) live.ws.send(JSON.stringify(message));
}
state.send = send;
state.liveFz = () => live.wrench.map((r) => r[3]);

function setPill(el, text, cls) { el.textContent = text; el.className = "pill " + (cls || ""); }

// "live" only when the link is up and the rig is open; "no rig" when it failed or is held elsewhere.
function showLink() {
  const rig = state.rig ? state.rig.state : "opening";
  if (state.protocol && live.linked) setPill($("link-status"), `running protocol ${state.protocol.name}`, "run");
  else if (rig === "open" && live.linked) setPill($("link-status"), "live", "ok");
  else if (rig === "opening") setPill($("link-status"), live.linked ? "connected; opening the rig…" : "connecting…", "");
  else if (live.linked || rig !== "open") setPill($("link-status"), "no rig", "bad");
}

async function drawFrame(buffer) {
  if (state.protocol) return;  // the run's own frames are shown meanwhile (showRunFrame)
  const n = new DataView(buffer).getUint32(0, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, n)));
  const bitmap = await createImageBitmap(new Blob([new Uint8Array(buffer, 4 + n)], { type: "image/jpeg" }));
  const canvas = $("live-frame");
  if (canvas.width !== header.width || canvas.height !== header.height) {
    canvas.width = header.width; canvas.height = header.height;
  }
  const ctx = canvas.getContext("2d", { willReadFrequently: true });
  ctx.drawImage(bitmap, 0, 0);
  if (!live.ref || live.ref.width !== canvas.width) live.ref = ctx.getImageData(0, 0, canvas.width, canvas.height);
  if ($("diff-view").checked) {
    // |frame - reference| x 4 around mid-grey: what the contact changed.
    const now = ctx.getImageData(0, 0, canvas.width, canvas.height);
    const a = now.data, r = live.ref.data;
    for (let i = 0; i < a.length; i += 4) {
      for (let c = 0; c < 3; c++) a[i + c] = Math.min(255, 4 * Math.abs(a[i + c] - r[i + c]));
    }
    ctx.putImageData(now, 0, 0);
  }
  state.frames += 1;
  state.frameIndex = header.index;
  state.frameT = header.t_s;
  canvas.dataset.index = String(header.index);
  canvas.dataset.count = String(state.frames);
  // frames drawn over the last second (not the gap between two draws, which swings with every frame)
  const t = performance.now();
  live.draws.push(t);
  while (live.draws.length && live.draws[0] < t - 1000) live.draws.shift();
  const span = live.draws.length > 1 ? (t - live.draws[0]) / 1000 : 0;
  const fps = span >= 0.5 ? (live.draws.length - 1) / span : null;
  state.fps = fps;
  $("frame-info").textContent = `#${header.index} · ${header.width}×${header.height} · ` +
    (fps == null ? "– fps" : `${fps.toFixed(1)} fps (drawn, last second)`);
  send({ type: "drawn", index: header.index, t_s: header.t_s });
}

// ---- marker flow: arrows from each reference marker along its motion, x scale ------------
const MIN_ARROW_PX = 1;  // drawn length (after scaling) below which a marker counts as still

function drawArrows(canvas, width, height, vectors, scale) {
  if (canvas.width !== width || canvas.height !== height) { canvas.width = width; canvas.height = height; }
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, width, height);
  ctx.lineWidth = 1.2;
  ctx.strokeStyle = "#00ff66";
  let drawn = 0, sx = 0, sy = 0;
  for (const [x, y, dx, dy] of vectors) {
    sx += dx; sy += dy;
    const ex = x + scale * dx, ey = y + scale * dy, len = Math.hypot(ex - x, ey - y);
    if (len < MIN_ARROW_PX) continue;
    drawn += 1;
    const head = Math.min(4, 0.4 * len), a = Math.atan2(ey - y, ex - x);
    ctx.beginPath();
    ctx.moveTo(x, y); ctx.lineTo(ex, ey);
    ctx.moveTo(ex, ey); ctx.lineTo(ex - head * Math.cos(a - 0.5), ey - head * Math.sin(a - 0.5));
    ctx.moveTo(ex, ey); ctx.lineTo(ex - head * Math.cos(a + 0.5), ey - head * Math.sin(a + 0.5));
    ctx.stroke();
  }
  const n = vectors.length || 1;
  return { arrows: drawn, matched: vectors.length, meanDx: sx / n, meanDy: sy / n };
}

function clearOverlay(canvas) { canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height); }

function onFlow(m) {
  if (!$("marker-flow").checked) return;
  const frame = $("live-frame");
  const summary = drawArrows($("flow-overlay"), frame.width, frame.height, m.vectors, m.scale);
  state.flow = { index: m.index, markers: m.markers, ...summary };
  state.flows += 1;
  state.flowComputeMs = m.compute_ms;
  const info = $("flow-info");
  info.hidden = false;
  info.textContent = `marker flow of frame #${m.index} against #${m.reference_index}, arrows ×${m.scale}: ` +
    `${summary.matched} of ${m.markers} markers matched, ${summary.arrows} of them moved; ` +
    `mean motion ${fixed(summary.meanDx, 2)}, ${fixed(summary.meanDy, 2)} px (x right, y down)`;
}

function onMessage(m) {
  if (m.type === "state") onState(m);
  else if (m.type === "history") { live.wrench = m.wrench; plotWrench(); }
  else if (m.type === "flow") onFlow(m);
  else if (m.type === "event") addEvent(m.level, `${m.at} ${m.text}`);
  else if (m.type === "control") setControl(m);
  else if (m.type === "rig") setRig(m);
  else if (m.type === "refused") { $("control-msg").textContent = m.text; addEvent("warn", m.text); }
}

function addEvent(level, text) {
  state.events.push(text);
  const li = document.createElement("li");
  li.className = level; li.textContent = text;
  const list = $("events");
  list.appendChild(li);
  list.scrollTop = list.scrollHeight;
}

function setControl(m) {
  state.control = m;
  const mine = !!(m && m.you);
  if (!m) setPill($("control-status"), "no control", "bad");
  else if (mine) setPill($("control-status"), "you have control", "ok");
  else if (m.holder) setPill($("control-status"), `controlled by ${m.holder} since ${m.since}`, "bad");
  else setPill($("control-status"), "nobody has control", "");
  applyLock();
  if (mine && !state.protocol) $("control-msg").textContent = "";
}

// Controls the server would refuse are disabled, each with the reason on it and in a line under them.
function applyLock() {
  const mine = !!(state.control && state.control.you);
  const running = state.protocol;
  const why = running ? `controls locked: protocol ${running.name} is running (STOP ends it)` :
    mine ? "" : "take control first";
  document.querySelectorAll(".needs-control").forEach((b) => { b.disabled = !mine || !!running; b.title = why; });
  const lock = $("lock-msg");
  lock.hidden = !running;
  lock.textContent = running ? why : "";
}

// The protocol's own newest frame in the live view's place (fetched from its run file, as the run browser).
async function showRunFrame(p) {
  if (!p.run || p.frame < 0 || live.runFrameBusy || live.runFrameShown === `${p.run}#${p.frame}`) return;
  live.runFrameBusy = true;
  try {
    const response = await fetch(`api/run/image?kind=frame&i=${p.frame}&name=${encodeURIComponent(p.run)}`);
    if (!response.ok || !state.protocol) return;
    const bitmap = await createImageBitmap(await response.blob());
    const canvas = $("live-frame");
    if (canvas.width !== bitmap.width || canvas.height !== bitmap.height) {
      canvas.width = bitmap.width; canvas.height = bitmap.height;
    }
    canvas.getContext("2d").drawImage(bitmap, 0, 0);
    canvas.dataset.index = String(p.frame);
    canvas.dataset.run = p.run;
    live.runFrameShown = `${p.run}#${p.frame}`;
    state.runFrame = { run: p.run, index: p.frame };
  } finally {
    live.runFrameBusy = false;
  }
}

// Who holds the rig: this console (its pid), or, when a device is held elsewhere, that process.
function rigUsable() { return !state.rig || state.rig.state === "open" || state.rig.state === "opening"; }

function setRig(m) {
  state.rig = m;
  const pill = $("rig-status");
  pill.hidden = false;
  pill.title = m.holder || m.error || "";
  if (m.state === "opening") setPill(pill, "opening the rig…", "");
  else if (m.state === "open") setPill(pill, `rig held by this console (pid ${m.pid})`, "ok");
  else if (m.state === "busy") {  // the pill says who; the line beside it (m.error) the whole story
    setPill(pill, `rig busy: ${m.device} held by ${m.holder_pid ? "pid " + m.holder_pid : "another process"}`, "bad");
  } else setPill(pill, m.state === "closed" ? "rig closed" : "rig failed to open", "bad");
  showLink();
  if (m.state === "open") { $("live").hidden = false; return; }
  if (rigUsable()) return;
  // nothing live: no frame, no jog; the header says why and who holds the device
  $("live").hidden = true;
  $("control-status").hidden = true;
  if (m.error) {
    const e = $("rig-error");
    e.hidden = false;
    e.textContent = m.state === "busy" ? m.error :
      `the rig did not open: ${m.error} — no live view and no jogging; fix it, then restart rig console ` +
      "(the run browser below works meanwhile)";
  }
}

function onState(m) {
  state.axes = m.axes;
  live.limits = m.limits;
  if (m.reset_trace) live.wrench = [];  // a protocol's own (simulated) clock began or ended
  state.simulatedTime = !!m.simulated_time;
  const was = state.protocol;
  state.protocol = m.protocol || null;
  state.tare = m.tare || null;
  state.axesSource = m.axes_source || "";
  if (state.protocol) {  // the run owns the camera: its own newest frame is shown, not the idle stream
    const p = state.protocol;
    $("frame-info").textContent = p.frame >= 0
      ? `#${p.frame} of ${p.run} · the protocol's newest frame (${p.phase}, level ${p.level}) · live view paused`
      : `protocol ${p.name} starting · live view paused`;
    live.draws = [];
    showRunFrame(p);
  }
  if (!!was !== !!state.protocol) { showLink(); applyLock(); }
  $("axes-source").textContent = state.axesSource ? `(${state.axesSource})` : "";
  for (const row of m.wrench) live.wrench.push(row);
  const last = live.wrench.length ? live.wrench[live.wrench.length - 1] : null;
  if (last) {
    while (live.wrench.length && live.wrench[0][0] < last[0] - HISTORY_S) live.wrench.shift();
    state.wrench = last.slice(1);
    $("wrench-now").textContent = COMPONENTS.map((c, i) => `${c} ${fixed(last[i + 1], 2)} ${UNITS[i]}`).join("  ") +
      (m.simulated_time ? " (a protocol's simulated time)" : "");
  }
  if (m.tare) {
    const t = $("tare-state");
    t.textContent = m.tare.tared ? "tared" : m.tare.text;
    t.className = "pill " + (m.tare.tared ? "ok" : "bad");
  }
  if (m.limits) {
    $("limits").textContent = "limits: " + COMPONENTS.map((c, i) => `|${c}| ≤ ${m.limits[i]}`).join(", ") +
      " (N, N·mm)" + (m.activity ? ` — moving: ${m.activity}` : "");
  }
  renderAxes(m.axes);
  plotWrench();
}

function renderAxes(axes) {
  const body = document.querySelector("#axes tbody");
  if (body.children.length !== Object.keys(axes).length) {
    body.innerHTML = "";
    const jog = $("jog");
    jog.innerHTML = "";
    for (const name of Object.keys(axes)) {
      const tr = document.createElement("tr");
      tr.id = `axis-${name}`;
      tr.innerHTML = `<td>${name}</td><td class="pos"></td><td class="st"></td><td class="homed"></td><td class="travel"></td><td class="warn"></td>`;
      body.appendChild(tr);
      const minus = jogButton(name, -1), plus = jogButton(name, +1);
      const label = document.createElement("span");
      label.textContent = name;
      const pos = document.createElement("span");
      pos.id = `jog-${name}-pos`;
      jog.append(label, minus, pos, plus);
    }
  }
  for (const [name, a] of Object.entries(axes)) {
    const tr = $(`axis-${name}`);
    tr.className = a.state;
    tr.querySelector(".pos").textContent = `${fixed(a.position, 4)} ${a.unit}`;
    tr.querySelector(".st").textContent = a.state;
    tr.querySelector(".homed").textContent = a.homed ? "yes" : "no";
    tr.querySelector(".travel").textContent = `${a.travel[0]} … ${a.travel[1]}`;
    tr.querySelector(".warn").textContent = a.warnings.join(" ");
    $(`jog-${name}-pos`).textContent = fixed(a.position, 3);
  }
}

function jogButton(axis, sign) {
  const b = document.createElement("button");
  b.type = "button";
  b.id = `jog-${axis}-${sign > 0 ? "plus" : "minus"}`;
  b.className = "needs-control";
  b.textContent = `${axis === "theta" ? "θ" : axis} ${sign > 0 ? "+" : "−"}`;
  b.title = `${axis} ${sign > 0 ? "+" : "−"} one step`;
  b.disabled = !(state.control && state.control.you);
  b.onclick = () => jog(axis, sign);
  return b;
}

function jog(axis, sign) { send({ type: "jog", axis, step: sign * parseFloat($("step").value) }); }

function plotWrench() {
  if (!live.forces) return;
  const rows = live.wrench;
  const t0 = rows.length ? rows[rows.length - 1][0] : 0;
  const xs = rows.map((r) => r[0] - t0);
  setChartData(live.forces, [xs, ...[1, 2, 3].map((k) => rows.map((r) => r[k]))]);
  setChartData(live.moments, [xs, ...[4, 5, 6].map((k) => rows.map((r) => r[k]))]);
}

function setUpLive(info) {
  $("live").hidden = !(info.rig && info.rig.state === "open");  // shown once the rig is open
  live.markerFlow = !!info.marker_flow;
  $("marker-flow-label").hidden = !live.markerFlow;
  $("live").hidden = false;  // laid out once, so the charts get their width
  live.forces = chart($("live-forces"), COMPONENTS.slice(0, 3), "N", COLORS.slice(0, 3), {}, [-HISTORY_S, 0], "t (s) before now");
  live.moments = chart($("live-moments"), COMPONENTS.slice(3), "N·mm", COLORS.slice(3), {}, [-HISTORY_S, 0], "t (s) before now");
  $("live").hidden = !(info.rig && info.rig.state === "open");
  state.charts = { forces: live.forces, moments: live.moments };
  $("take-control").onclick = () => send({ type: "take_control" });
  $("release-control").onclick = () => send({ type: "release_control" });
  $("stop").onclick = () => send({ type: "stop" });
  $("zero").onclick = () => send({ type: "zero" });
  $("home").onclick = () => send({ type: "home" });
  for (const name of info.protocols || []) {
    const o = document.createElement("option");
    o.value = name; o.textContent = name;
    $("protocol-select").appendChild(o);
  }
  if ((info.protocols || []).includes("sphere10mm")) $("protocol-select").value = "sphere10mm";  // the docs' example
  $("protocol-row").hidden = !(info.protocols || []).length;
  $("run-protocol").onclick = () => {
    const origin = $("protocol-origin").value.split(",").map((v) => Number(v.trim()));
    send({ type: "run_protocol", name: $("protocol-select").value, origin, settings: protocolSettings() });
  };
  $("protocol-select").onchange = showPlan;
  $("protocol-set").oninput = () => { clearTimeout(live.planTimer); live.planTimer = setTimeout(showPlan, 300); };
  showPlan();
  $("set-reference").onclick = () => { live.ref = null; if (live.markerFlow) send({ type: "set_reference" }); };
  $("marker-flow").onchange = (e) => {
    send({ type: "flow", on: e.target.checked });
    if (!e.target.checked) { clearOverlay($("flow-overlay")); $("flow-info").hidden = true; state.flow = null; }
  };
  document.addEventListener("keydown", onKey);
  connect();
}

// ---- a protocol's plan before it starts: duration, frames, disk, with the --set values --------
function protocolSettings() {
  return $("protocol-set").value.split(/[;\n]/).map((v) => v.trim()).filter((v) => v);
}

async function showPlan() {
  const name = $("protocol-select").value;
  if (!name) return;
  const query = [`name=${encodeURIComponent(name)}`].concat(protocolSettings().map((v) => `set=${encodeURIComponent(v)}`));
  const plan = await fetch("api/protocol?" + query.join("&")).then((r) => r.json()).catch(() => ({ error: "no answer" }));
  state.plan = plan;
  const el = $("protocol-plan");
  if (plan.error) { el.textContent = plan.error; el.className = "plan error"; return; }
  el.className = "plan";
  if ($("control-msg").textContent.startsWith("run protocol refused")) $("control-msg").textContent = "";
  el.textContent = `${plan.name} (${plan.object}, ${plan.sensor}): ${plan.duration} of protocol time, ` +
    `${plan.frames} frames at ${plan.capture_hz} Hz, ${plan.disk}` +
    (plan.simulated_time ? "; on the simulated rig it runs on simulated time, as rig run-protocol --sim" : "");
}

const KEYS = {
  ArrowLeft: ["x", -1], ArrowRight: ["x", 1], ArrowUp: ["y", 1], ArrowDown: ["y", -1],
  PageUp: ["z", 1], PageDown: ["z", -1], "[": ["theta", -1], "]": ["theta", 1],
};

function onKey(e) {
  if (e.target.tagName === "INPUT" || e.target.tagName === "SELECT") return;
  if (e.key === "Escape" || e.key === " ") { send({ type: "stop" }); e.preventDefault(); return; }
  if ("1234".includes(e.key) && e.key.length === 1) { $("step").selectedIndex = Number(e.key) - 1; return; }
  const move = KEYS[e.key];
  if (move && state.control && state.control.you) { jog(move[0], move[1]); e.preventDefault(); }
}

// ---- the run browser --------------------------------------------------------------------
const browser = { name: null, run: null, charts: [], timer: null };

async function listRuns(select) {
  const runs = await (await fetch("api/runs")).json();
  const sel = $("run-select");
  const keep = select || sel.value;
  sel.innerHTML = '<option value="">choose a run file…</option>';
  for (const r of runs) {
    const o = document.createElement("option");
    o.value = r.name; o.textContent = `${r.name} (${(r.bytes / 1e6).toFixed(1)} MB)`;
    sel.appendChild(o);
  }
  if (keep && runs.some((r) => r.name === keep)) { sel.value = keep; await openRun(keep); }
}

// Each phase a shaded band over the plot (drawn before the traces); its name in the strip above the plot
// (drawn after them, so no trace hides it), centred over its own band and only where it fits there.
function phaseSpans(u) {
  const run = browser.run, spans = [];
  if (!run || !run.t_s.length) return spans;
  let start = 0;
  for (let i = 1; i <= run.t_s.length; i++) {
    if (i === run.t_s.length || run.phase_index[i] !== run.phase_index[start]) {
      // a phase's band runs from its first frame to the next phase's first frame
      const end = i < run.t_s.length ? run.t_s[i] : run.t_s[i - 1];
      spans.push({ x0: u.valToPos(run.t_s[start], "x", true), x1: u.valToPos(end, "x", true), p: run.phase_index[start] });
      start = i;
    }
  }
  return spans;
}

function phaseBands(u) {
  const ctx = u.ctx, top = u.bbox.top, h = u.bbox.height;
  for (const b of phaseSpans(u)) {
    ctx.fillStyle = PHASE_COLORS[b.p % PHASE_COLORS.length];
    ctx.fillRect(b.x0, top, Math.max(1, b.x1 - b.x0), h);
  }
}

function phaseLabels(u) {
  const run = browser.run, ctx = u.ctx, dpr = devicePixelRatio;
  if (!run) return;
  ctx.save();
  ctx.font = `${10 * dpr}px sans-serif`;
  ctx.fillStyle = "#333";
  ctx.textBaseline = "bottom";
  const placed = [];
  for (const b of phaseSpans(u)) {
    const name = run.phases[b.p] || "?", w = ctx.measureText(name).width;
    if (w + 4 * dpr > b.x1 - b.x0) continue;  // the band is too narrow for its name: none rather than a wrong one
    const x = (b.x0 + b.x1 - w) / 2;
    ctx.fillText(name, x, u.bbox.top - 3 * dpr);
    placed.push({ name, x0: x / dpr, x1: (x + w) / dpr, band: [b.x0 / dpr, b.x1 / dpr] });
  }
  ctx.restore();
  u.phaseLabels = placed;  // what tests read: each label's extent (CSS px) and its own band's
}

function atSlider() {
  const run = browser.run;
  return run && run.frames ? Math.min(Number($("run-slider").value), run.frames - 1) : null;
}

function frameMarker(u) {
  const run = browser.run;
  if (!run || !run.t_s.length) return;
  const i = Number($("run-slider").value);
  const x = u.valToPos(run.t_s[Math.min(i, run.t_s.length - 1)], "x", true);
  u.ctx.strokeStyle = "#000"; u.ctx.lineWidth = 2 * devicePixelRatio;
  u.ctx.beginPath(); u.ctx.moveTo(x, u.bbox.top); u.ctx.lineTo(x, u.bbox.top + u.bbox.height); u.ctx.stroke();
}

async function openRun(name) {
  clearTimeout(browser.timer);
  if (!name) { $("run-view").hidden = true; return; }
  const response = await fetch("api/run?name=" + encodeURIComponent(name));
  const run = await response.json();
  if (run.error) { $("run-info").textContent = run.error; return; }
  const fresh = browser.name !== name;
  browser.name = name; browser.run = run; state.run = run;
  $("run-view").hidden = false;
  $("run-flow-label").hidden = !run.sensor.endsWith("_markers");
  if (!run.sensor.endsWith("_markers")) $("run-flow").checked = false;
  $("run-info").textContent = `${run.protocol} · ${run.object} · ${run.sensor} · ${run.frames} / ${run.frames_planned} frames written · ` +
    statusText(run.status, run.reason) + ` · phases: ${run.phases.join(", ")}`;
  const slider = $("run-slider");
  const wasAtEnd = Number(slider.value) >= Number(slider.max);
  slider.max = String(Math.max(0, run.frames - 1));
  if (fresh) {
    browser.charts.forEach((c) => c.destroy());
    const hooks = { drawClear: [phaseBands], draw: [frameMarker, phaseLabels] };
    state.runCharts = browser.charts = [
      chart($("run-forces"), COMPONENTS.slice(0, 3), "N", COLORS.slice(0, 3), hooks, null, "t (s) from the first frame", atSlider),
      chart($("run-moments"), COMPONENTS.slice(3), "N·mm", COLORS.slice(3), hooks, null, "t (s) from the first frame", atSlider),
      chart($("run-pose"), ["x", "y", "z", "θ"], ["mm", "mm", "mm", "deg"], ["#d62728", "#2ca02c", "#1f77b4", "#7f7f7f"],
        hooks, null, "t (s) from the first frame", atSlider),
    ];
    $("run-reference").src = run.has.reference ? `api/run/image?kind=reference&name=${encodeURIComponent(name)}` : "";
    slider.value = "0";
  } else if (wasAtEnd) {
    slider.value = slider.max;  // following a run being written: stay on its newest frame
  }
  const col = (rows, k) => rows.map((r) => r[k]);
  setChartData(browser.charts[0], [run.t_s, col(run.wrench, 0), col(run.wrench, 1), col(run.wrench, 2)]);
  setChartData(browser.charts[1], [run.t_s, col(run.wrench, 3), col(run.wrench, 4), col(run.wrench, 5)]);
  setChartData(browser.charts[2], [run.t_s, col(run.pose, 0), col(run.pose, 1), col(run.pose, 2), col(run.pose, 3)]);
  showFrame(Number(slider.value));
  if (run.status === "running") browser.timer = setTimeout(() => openRun(name), 2000);
}

function showFrame(i) {
  const run = browser.run;
  if (!run || !run.frames) return;
  const img = $("run-frame");
  img.onload = () => { img.dataset.index = String(i); };
  img.onerror = async () => {  // a frame the server refused (damaged: 422): its one line, in place of the frame
    const m = await fetch(img.src).then((r) => r.json()).catch(() => ({}));
    if (m.error && Number($("run-slider").value) === i) $("run-frame-caption").textContent = m.error;
  };
  img.src = `api/run/image?kind=frame&i=${i}&name=${encodeURIComponent(browser.name)}`;
  const w = run.wrench[i], p = run.pose[i];
  $("run-frame-label").textContent = `frame #${i} of ${run.frames} · t = ${fixed(run.t_s[i], 2)} s · ${run.phases[run.phase_index[i]] || "?"}`;
  $("run-wrench").textContent = COMPONENTS.map((c, k) => `${c} ${fixed(w[k], 3)} ${UNITS[k]}`).join("  ") +
    `   pose x ${fixed(p[0], 3)} mm  y ${fixed(p[1], 3)} mm  z ${fixed(p[2], 3)} mm  θ ${fixed(p[3], 2)} deg`;
  $("run-wrench").dataset.index = String(i);
  showCondition(i);
  browser.charts.forEach((c) => { c.redraw(false); if (c.cursor.idx == null) c.setLegend({ idx: null }); });
  showRunFlow(i);
}

// The condition panel: the object image placed at frame i's measured pose, as the model gets it.
async function showCondition(i) {
  const run = browser.run, img = $("run-object"), caption = $("run-object-caption");
  if (!run.has.object) { img.removeAttribute("src"); caption.textContent = "no object image in this run"; return; }
  const name = browser.name;
  const response = await fetch(`api/run/image?kind=condition&i=${i}&name=${encodeURIComponent(name)}`);
  if (name !== browser.name || Number($("run-slider").value) !== i) return;  // the slider moved on
  if (!response.ok) {
    const m = await response.json().catch(() => ({}));
    caption.textContent = m.error || "the condition could not be shown";
    return;
  }
  const pose = JSON.parse(response.headers.get("x-pose") || "{}");
  const url = URL.createObjectURL(await response.blob());
  img.onload = () => { img.dataset.index = String(i); URL.revokeObjectURL(url); };
  img.src = url;
  state.condition = { index: i, ...pose };
  caption.textContent = `object at this frame's pose (the condition): x ${fixed(pose.x_mm, 3)} mm, ` +
    `y ${fixed(pose.y_mm, 3)} mm, θ ${fixed(pose.theta_deg, 2)} deg`;
}

async function showRunFlow(i) {
  const overlay = $("run-flow-overlay");
  if (!$("run-flow").checked) { clearOverlay(overlay); state.runFlow = null; $("run-frame-caption").textContent = "frame"; return; }
  const name = browser.name;
  const m = await (await fetch(`api/run/flow?i=${i}&name=${encodeURIComponent(name)}`)).json();
  if (name !== browser.name || Number($("run-slider").value) !== i) return;  // the slider moved on
  if (m.error) { $("run-frame-caption").textContent = m.error; return; }
  const run = browser.run;
  const img = $("run-frame");
  const summary = drawArrows(overlay, img.naturalWidth || 256, img.naturalHeight || 256, m.vectors, m.scale);
  state.runFlow = { index: i, markers: m.markers, ...summary };
  $("run-frame-caption").textContent = `frame, marker flow ×${m.scale} against the reference ` +
    `(${summary.matched} of ${m.markers} markers matched, ${summary.arrows} of them moved)` + (run ? "" : "");
}

// ---- runs in progress: `rig run-protocol` writing into a listed folder -------------------
function fmtDuration(s) {
  s = Math.max(0, Math.round(s));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return (h ? `${h}h${String(m).padStart(2, "0")}m` : `${m}m`) + `${String(sec).padStart(2, "0")}s`;
}

function progressCard(p, i) {
  let card = $(`progress-${i}`);
  if (!card) {
    card = document.createElement("div");
    card.id = `progress-${i}`;
    card.innerHTML = `<img alt="latest frame"><div><div class="title"></div><progress max="1" value="0"></progress>` +
      `<table class="facts"><tbody></tbody></table><p class="mono pair"></p>` +
      `<button type="button">open in the run browser</button></div>`;
    $("progress-list").appendChild(card);
  }
  card.className = "progress-card" + (p.finished ? " finished" : "") + (p.stale ? " stale" : "");
  card.dataset.run = p.run;
  card.querySelector("button").onclick = async () => { $("run-select").value = p.run; await listRuns(p.run); };
  const title = card.querySelector(".title");
  if (p.error) { title.textContent = p.error; title.className = "title error"; return; }
  title.className = "title";
  const rows = [];
  if (p.finished) {
    title.textContent = `${p.run}: ended`;
    rows.push(["status", statusText(p.file_status, p.file_reason)]);
    rows.push(["frames", `${p.committed} / ${p.frames_planned}`]);
  } else {
    title.textContent = `${p.protocol} → ${p.run}` + (p.stale ? ` — no update for ${fmtDuration(p.age_s)}: the writer stopped?` : "");
    if (p.stale) title.className = "title error";
    const depth = p.depth_mm === null ? "" : ` (depth ${p.depth_mm.toFixed(2)} mm)`;
    // one frame count: the frames the file holds (the run browser's count too), not the sidecar's
    const written = p.committed != null ? p.committed : p.frame;
    rows.push(["phase", p.phase], ["level", `${p.level}${depth}`], ["frames", `${written} / ${p.frames} written`],
      ["ETA", `${fmtDuration(p.eta_s)} (protocol time ${p.t_protocol_s.toFixed(0)} of ${p.duration_s.toFixed(0)} s)`],
      ["updated", `${p.age_s.toFixed(1)} s ago`]);
    card.querySelector("progress").value = written / p.frames;
  }
  if (p.finished) card.querySelector("progress").value = p.frames_planned ? p.committed / p.frames_planned : 1;
  const body = card.querySelector("tbody");
  body.innerHTML = "";
  for (const [k, v] of rows) {
    const tr = document.createElement("tr");
    tr.className = `fact-${k.toLowerCase()}`;
    tr.innerHTML = "<td></td><td></td>";
    tr.children[0].textContent = k; tr.children[1].textContent = v;
    body.appendChild(tr);
  }
  const pair = card.querySelector(".pair");
  if (p.file_error) pair.textContent = p.file_error;
  else if (p.committed > 0 && p.latest_wrench) {
    const w = p.latest_wrench, q = p.latest_pose;
    pair.textContent = `latest pair, frame #${p.committed - 1}: ` +
      COMPONENTS.map((c, k) => `${c} ${fixed(w[k], 3)} ${UNITS[k]}`).join("  ") +
      `   pose x ${fixed(q[0], 3)} mm  y ${fixed(q[1], 3)} mm  z ${fixed(q[2], 3)} mm  θ ${fixed(q[3], 2)} deg`;
    const img = card.querySelector("img");
    const want = p.committed - 1;
    if (img.dataset.index !== String(want)) {
      const src = `api/run/image?kind=frame&i=${want}&name=${encodeURIComponent(p.run)}`;
      img.onload = () => { img.dataset.index = String(want); };
      img.src = src;
    }
  } else pair.textContent = "no frame committed yet";
}

async function pollProgress() {
  try {
    const list = await (await fetch("api/progress")).json();
    state.progress = list;
    state.progressPolls += 1;
    $("progress").hidden = list.length === 0;
    const cards = $("progress-list");
    while (cards.children.length > list.length) cards.removeChild(cards.lastChild);
    list.forEach(progressCard);
    const runs = Array.from($("run-select").options).map((o) => o.value);
    if (list.some((p) => !runs.includes(p.run))) listRuns();  // a new run file appeared
  } catch (e) {
    // the server is gone or restarting: keep polling, the link pill says the rest
  }
  setTimeout(pollProgress, state.progressEveryMs);
}

function setUpBrowser(openName) {
  $("run-select").onchange = (e) => openRun(e.target.value);
  $("run-refresh").onclick = () => listRuns();
  $("run-slider").oninput = (e) => showFrame(Number(e.target.value));
  $("run-flow").onchange = () => showRunFlow(Number($("run-slider").value));
  listRuns(openName);
}

(async function main() {
  const info = await (await fetch("api/info")).json();
  if (info.rig_error) { const e = $("rig-error"); e.hidden = false; e.textContent = info.rig_error; }
  if (info.live) setUpLive(info);
  if (info.rig) setRig(info.rig);
  else { setPill($("link-status"), "run browser only", ""); $("control-status").hidden = true; }
  setUpBrowser(info.open_run);
  pollProgress();
})();
