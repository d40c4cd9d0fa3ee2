// rig console: what the live view and the run browser share: the page's state, numbers as shown, the charts.
// No build step: plain browser JavaScript and the vendored uPlot (static/vendor, MIT); the page loads
// charts.js, then console.js (the live rig over one WebSocket), then runs.js (the run browser, runs in
// progress, over plain HTTP). Scripts share one global scope.
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

// A chart as wide as its box, now and whenever the box changes (a chart laid out wider than an 800 px
// window was cut off at its right, x stopping at 52 of 86 s).
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
  charts.set(target, u);
  boxes.observe(target);
  return u;
}

// Each chart follows its box: a window resized, and a scrollbar appearing as the page grows (the box some
// 15 px narrower with no resize event: the chart's right end, the time axis's "0", was cut off).
const charts = new Map();  // box -> its chart (the newest: the run browser makes new ones in the same boxes)
const boxes = new ResizeObserver((entries) => {
  for (const e of entries) {
    const u = charts.get(e.target), w = chartWidth(e.target);
    if (u && e.target.isConnected && w !== u.width) u.setSize({ width: w, height: u.height });
  }
});

// New data, and the legend's values with it while the cursor is off the chart.
function setChartData(u, data) {
  u.setData(data);
  if (u.cursor.idx == null) u.setLegend({ idx: null });
}

const UNITS = ["N", "N", "N", "N·mm", "N·mm", "N·mm"];

// The last minute is 3000 samples for some 500 px: drawn as they are, a gauge's quantisation (Mz flipping
// between 1 and 2 N·mm every 20 ms) filled every pixel column from 1 to 2, a solid bar. Per two pixels, a
// series that moved less than a tenth of its chart's least span there (noise) is drawn at its mean, one that
// moved more (a contact, a spike) at its least and greatest, in their order; the newest sample as it is.
function plotRows(u, rows, cols, minSpan) {
  const n = rows.length, t0 = n ? rows[n - 1][0] : 0;
  const bucketS = (2 * HISTORY_S) / Math.max(50, u.bbox.width / devicePixelRatio), noise = minSpan / 10;
  const xs = [], ys = cols.map(() => []);
  for (let i = 0; i < n - 1;) {
    const b = Math.floor(rows[i][0] / bucketS);
    let j = i + 1;
    while (j < n - 1 && Math.floor(rows[j][0] / bucketS) === b) j++;
    const ends = j - i > 1 ? [rows[i][0] - t0, rows[j - 1][0] - t0] : [rows[i][0] - t0];
    xs.push(...ends);
    cols.forEach((k, c) => {
      let lo = i, hi = i, sum = 0;
      for (let m = i; m < j; m++) {
        sum += rows[m][k];
        if (rows[m][k] < rows[lo][k]) lo = m;
        if (rows[m][k] > rows[hi][k]) hi = m;
      }
      if (ends.length === 1) ys[c].push(rows[i][k]);
      else if (rows[hi][k] - rows[lo][k] < noise) ys[c].push(sum / (j - i), sum / (j - i));
      else ys[c].push(...(lo < hi ? [rows[lo][k], rows[hi][k]] : [rows[hi][k], rows[lo][k]]));
    });
    i = j;
  }
  if (n) { xs.push(0); cols.forEach((k, c) => ys[c].push(rows[n - 1][k])); }
  setChartData(u, [xs, ...ys]);
}
