// rig console: the live rig over one WebSocket (charts.js before it, runs.js after it).
"use strict";

// ---- the live rig -------------------------------------------------------------------------
const live = { ws: null, ref: null, wrench: [], forces: null, moments: null, limits: null, draws: [], flowScale: 5, linked: false };

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
  if (state.protocol) return;  // a protocol began while this frame was decoded: its frame stays
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
  // a refusal because a protocol was running is no longer true once it has ended
  const msg = $("control-msg");
  if (!running && / is running \(STOP ends it\)$|a protocol is running/.test(msg.textContent)) msg.textContent = "";
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
  plotRows(live.forces, live.wrench, [1, 2, 3], MIN_SPAN.N);
  plotRows(live.moments, live.wrench, [4, 5, 6], MIN_SPAN["N·mm"]);
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
  if (!move || !(state.control && state.control.you)) return;
  e.preventDefault();
  if (state.protocol) {  // refused here, as the buttons are: nothing sent for the server to refuse
    $("control-msg").textContent = `${e.key} not sent: protocol ${state.protocol.name} is running (STOP ends it)`;
  } else jog(move[0], move[1]);
}
