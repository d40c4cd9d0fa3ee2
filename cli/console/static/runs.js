// rig console: the run browser and the runs in progress, over plain HTTP (after charts.js and console.js).
"use strict";

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
// (drawn after them, so no trace hides it), centred over its own band: shortened ("untw…") where the band
// is narrower than the name, left out where not even that fits, never spilling into the next band.
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

// The name as it fits in room (canvas px): whole, else its first letters and "…" (two at least), else null.
function fitName(ctx, name, room) {
  if (ctx.measureText(name).width <= room) return name;
  for (let k = name.length - 1; k >= 2; k--) {
    const short = name.slice(0, k) + "…";
    if (ctx.measureText(short).width <= room) return short;
  }
  return null;
}

function phaseLabels(u) {
  const run = browser.run, ctx = u.ctx, dpr = devicePixelRatio;
  if (!run) return;
  ctx.save();
  ctx.font = `${10 * dpr}px sans-serif`;
  ctx.fillStyle = "#333";
  ctx.textBaseline = "bottom";
  ctx.textAlign = "left";  // not uPlot's last axis's ("right" after the y ticks): the name from x rightwards
  const placed = [], baseline = u.bbox.top - 3 * dpr;  // the strip above the plot: no trace is drawn there
  for (const b of phaseSpans(u)) {
    const name = run.phases[b.p] || "?", text = fitName(ctx, name, b.x1 - b.x0 - 4 * dpr);
    if (!text) continue;  // too narrow even for "ab…": none rather than one over the next band
    const w = ctx.measureText(text).width, x = (b.x0 + b.x1 - w) / 2;
    ctx.fillText(text, x, baseline);
    placed.push({ name, text, x0: x / dpr, x1: (x + w) / dpr, bottom: baseline / dpr, band: [b.x0 / dpr, b.x1 / dpr] });
  }
  ctx.restore();
  u.phaseLabels = placed;  // what tests read: each label's extent (CSS px on the canvas) and its own band's
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
