// Live view (`#/sessions/{id}`): the session's stream in plots redrawn once per animation frame, the
// per-stride overlay, data health, controls, events and the 3D leg view. The phase plot overlays the phase
// of every estimator of the session's stack (the primary, which drives the torque, drawn widest). A stack with
// the speed-change intent estimator (seed 001) adds its desired vs actual speed, its detections marked. The
// hip and knee flexion come from the gait state's thigh and shank angles (sensed, or derived from raw IMUs by
// the stack's front ends); a stack with the SDRE estimator (`sdre_knee`, seed 002) adds its knee, dashed. A stack
// with the GP-EKF (`gp_ekf`, seed 003) gets its card (`gp_learning.js`): its phase is the STANCE phase, plotted
// there and kept out of the gait-phase plot.

import { api, errorText, openSessionStream } from "./api.js";
import { actorSelect, mountControls } from "./controls.js";
import { EVENT_COLORS, EventList } from "./events.js";
import { GP_EKF, gpLearningCard } from "./gp_learning.js";
import { COLORS, markersPlugin, Plot, Ring, StrideOverlay } from "./plots.js";
import { errorBox, fmt, h, runAction, showError } from "./ui.js";

export const WINDOW_S = 10; // seconds of full-rate history the live plots show
const RING_CAPACITY = 2048; // > 10 s at the 60 Hz the stream is asked for (34 s), bounded memory
const STALE_MS = 1000;
const COLUMNS = ["t", "phase_pct", "tbe_pct", "phase_rate", "incline_deg", "stride_length_m", "torque_Nm",
  "foot_angle_deg", "foot_pred_deg", "shank_angle_deg", "shank_pred_deg", "desired_speed_m_s", "speed_m_s",
  "hip_flex_deg", "knee_flex_deg", "knee_sdre_deg"];

/** The plots of a gait-state series; `review.js` uses the same list. */
export const PLOT_SPECS = [
  { key: "phase", title: "Phase: EKF and timing-based", yLabel: "% of cycle", yRange: [0, 100],
    cols: ["phase_pct", "tbe_pct"], series: [{ label: "phase", color: COLORS.blue }, { label: "timing-based", color: COLORS.orange, dash: [6, 4] }] },
  { key: "phase_rate", title: "Phase rate", yLabel: "1/s", cols: ["phase_rate"], series: [{ label: "phase rate", color: COLORS.blue }] },
  { key: "incline", title: "Incline", yLabel: "deg", cols: ["incline_deg"], series: [{ label: "incline", color: COLORS.green }] },
  { key: "stride_length", title: "Stride length", yLabel: "m", cols: ["stride_length_m"], series: [{ label: "stride length", color: COLORS.teal }] },
  { key: "torque", title: "Torque command", yLabel: "N·m", cols: ["torque_Nm"], series: [{ label: "torque", color: COLORS.orange }] },
  { key: "foot", title: "Foot angle: measured and predicted", yLabel: "deg", cols: ["foot_angle_deg", "foot_pred_deg"],
    series: [{ label: "measured", color: COLORS.blue }, { label: "predicted", color: COLORS.orange, dash: [6, 4] }] },
  { key: "shank", title: "Shank angle: measured and predicted", yLabel: "deg", cols: ["shank_angle_deg", "shank_pred_deg"],
    series: [{ label: "measured", color: COLORS.blue }, { label: "predicted", color: COLORS.orange, dash: [6, 4] }] },
  // the conventions of sessions/schema.py: thigh and shank from vertical, positive with the distal end forward;
  // fixed range: the knee bends to about 65 deg in swing, the thigh reaches about -25 deg at toe-off
  { key: "joints", title: "Hip and knee flexion (the hip assumes an upright pelvis)", yLabel: "deg", yRange: [-30, 80],
    cols: ["hip_flex_deg", "knee_flex_deg"],
    series: [{ label: "hip (thigh from vertical)", color: COLORS.purple }, { label: "knee (thigh − shank)", color: COLORS.green }] },
];

/** The SDRE estimator's (`sdre_knee`, seed 002) knee on the joints plot, when the stack runs it. */
export const SDRE_KNEE = { col: "knee_sdre_deg", series: { label: "knee, SDRE (sdre_knee)", color: COLORS.orange, dash: [6, 4] } };

/**
 * Knee flexion (deg, flexion positive) from the thigh and shank angles: null when either is missing.
 * @param {number | null | undefined} thigh @param {number | null | undefined} shank
 * @returns {number | null}
 */
export const kneeFlexion = (thigh, shank) => (thigh == null || shank == null ? null : thigh - shank);

/**
 * The speed-change intent estimator's (`intent`, seed 001) desired and actual speed; `review.js` uses it too.
 * Both hold between mid-stances (twice per step), where the filter updates them; 0 before its first one.
 */
export const INTENT_SPEC = {
  key: "intent", title: "Speed-change intent: desired vs actual speed", yLabel: "m/s", cols: ["desired_speed_m_s", "speed_m_s"],
  series: [{ label: "desired", color: COLORS.blue, width: 2.5 }, { label: "actual (CoM, mid-stance)", color: COLORS.teal, dash: [6, 4] }],
};

/** An intent output as plotted: null before the filter has started (0). */
export const intentValue = (v) => (v == null || !(v > 0) ? null : v);

/** A `GaitState` as one row of plot columns (phase in % of the cycle; hip flexion as the thigh angle). */
export function stateRow(s) {
  return { ...s, phase_pct: s.phase * 100, tbe_pct: s.tbe_phase * 100, hip_flex_deg: s.thigh_angle_deg,
    knee_flex_deg: kneeFlexion(s.thigh_angle_deg, s.shank_angle_deg) };
}

const ESTIMATOR_COLORS = [COLORS.blue, COLORS.orange, COLORS.green, COLORS.purple, COLORS.teal, COLORS.grey];

/** Ring column of an estimator's phase (% of the cycle). */
const estColumn = (name) => `est_${name}_pct`;

/** Estimators whose `phase` output is a stance phase, not the gait phase (% of the cycle) the phase plot shows. */
export const STANCE_PHASE = new Set([GP_EKF]);

/**
 * The phase plot's spec for a stack: one line per estimator that estimates a gait phase (from a batch's
 * `estimators`, less `STANCE_PHASE` ones), the primary widest and named; `failed` ones marked.
 * @param {string[]} names @param {string | null} primary @param {Set<string>} failed
 */
export function phaseSpec(names, primary, failed) {
  const label = (n) => `${n}${n === primary ? " (primary: drives the torque)" : ""}${failed.has(n) ? " (failed)" : ""}`;
  const title = !primary ? "Phase of every estimator; no primary: torque 0"
    : STANCE_PHASE.has(primary) ? `Gait phase of every estimator; the torque follows ${primary}'s stance phase (its card)`
      : `Phase of every estimator; the torque follows ${primary}`;
  return {
    key: "phase", yLabel: "% of cycle", yRange: [0, 100], title,
    cols: names.map(estColumn),
    series: names.map((n, i) => ({ label: label(n), color: ESTIMATOR_COLORS[i % ESTIMATOR_COLORS.length],
      width: n === primary ? 3 : 1.5, dash: n === primary ? undefined : [6, 4] })),
  };
}

/** Mean +/- SD band plot over the gait cycle. */
export function bandPlot(container, title, yLabel, color, fill) {
  return new Plot(container, {
    title, yLabel, xLabel: "% of gait cycle", xRange: [0, 100], height: 190,
    series: [{ label: "mean", color, width: 3 }, { label: "−1 SD", color: fill.line, width: 1 },
      { label: "+1 SD", color: fill.line, width: 1 }, { label: "newest stride", color: COLORS.grey, dash: [4, 4], width: 1.5 },
      { label: "baseline", color: "#111827", dash: [10, 5], width: 2 }],
    bands: [{ series: [3, 2], fill: fill.band }],
  });
}

/** Resolves the leg view's address for this browser: a loopback URL is moved to the dashboard's host. */
export function viewerUrl(url) {
  const u = new URL(url);
  const loop = (host) => ["127.0.0.1", "localhost", "[::1]"].includes(host);
  if (loop(u.hostname) && !loop(location.hostname)) u.hostname = location.hostname;
  return u.toString();
}

/** The 3D leg view iframe (or why it is missing); `focus` tells the server what to show. */
export function legView(focus) {
  const box = h("section", { class: "card leg-card" }, h("h2", { text: "3D leg view" }));
  const msg = h("p", { class: "hint", "data-testid": "leg-view-message" });
  box.append(msg);
  api("GET", "/api/viewer").then((v) => {
    if (!v.url) {
      msg.textContent = "The leg view is switched off on this server.";
      return;
    }
    box.append(h("iframe", { title: "3D leg view", "data-testid": "leg-view", src: viewerUrl(v.url), loading: "lazy" }));
    return focus && api("POST", "/api/viewer/focus", focus);
  }).catch((err) => {
    msg.textContent = `The leg view is unavailable: ${errorText(err)}`;
  });
  return box;
}

export function mountLive(root, sessionId) {
  let ring = new Ring(RING_CAPACITY, COLUMNS);
  // the session's estimators with a gait phase (known from the first batch; `phased`: with any phase, the
  // primary's choices), the one driving the torque, failures
  const stack = { names: [], phased: [], primary: null, failed: new Map(), key: "" };
  const overlay = new StrideOverlay(["torque_Nm", "foot_angle_deg", "phase_rate", "stride_length_m", "incline_deg"]);
  const events = new EventList("events-list");
  let intentMarks = []; // the detected intents, marked on the intent plot
  const addEvents = (...evs) => {
    events.add(...evs);
    if (evs.some((e) => e.kind === "intent")) {
      intentMarks = [...events.events.values()].filter((e) => e.kind === "intent")
        .map((e) => ({ t: e.t, color: EVENT_COLORS.intent, width: 2, dash: [4, 3] }));
    }
  };
  let lastT = -Infinity;
  let lastBatchAt = 0;
  let dataDirty = false;
  let strideDirty = false;
  let lastText = 0;
  let raf = 0;
  let lastStatePoll = performance.now();
  let alive = true;

  // --- header, summary, health --------------------------------------------------------------------
  const title = h("h1", { "data-testid": "live-title", text: `Session ${sessionId}` });
  const indicator = h("div", { class: "indicator stale", "data-testid": "live-indicator", role: "status", text: "NO DATA" });
  const conn = h("span", { class: "hint", "data-testid": "connection", text: "connecting…" });
  const streamError = errorBox("stream-error");
  const cell = (key, label, unit) => {
    const v = h("span", { class: "value", "data-testid": `summary-${key}`, text: "–" });
    return [h("div", { class: "metric" }, h("span", { class: "label", text: label }), v, h("span", { class: "unit", text: unit })), v];
  };
  const [phaseCell, phaseV] = cell("phase", "Phase", "%");
  const phaseLabel = phaseCell.querySelector(".label");
  const [cadCell, cadV] = cell("cadence", "Cadence", "strides/min");
  const [slCell, slV] = cell("stride-length", "Stride length", "m");
  const [spCell, spV] = cell("speed", "Speed", "m/s");
  const [incCell, incV] = cell("incline", "Incline", "deg");
  const [pkCell, pkV] = cell("peak-torque", "Peak torque, last stride", "N·m");
  // seed 001's speed-change intent, when the session runs it (`intent`): what the walker is about to do
  const [intentCell, intentV] = cell("intent", "Speed-change intent", "");
  const intentUnit = intentCell.querySelector(".unit");
  intentCell.hidden = true;
  const summary = h("div", { class: "summary", "data-testid": "summary" }, phaseCell, cadCell, slCell, spCell, incCell, pkCell, intentCell);

  const hv = (key) => h("dd", { "data-testid": `health-${key}`, text: "–" });
  const health = { t: hv("session-time"), rate: hv("rate"), latency: hv("latency"), serverLatency: hv("server-latency"), input: hv("dropped-input"), client: hv("dropped-client"), clients: hv("clients"), samples: hv("samples"), implausible: hv("implausible"), faults: hv("faults"), disk: hv("disk"),
    primary: hv("primary"), failedEstimators: hv("failed-estimators"), tracking: hv("tracking"), imu: hv("imu") };
  const healthCard = h("section", { class: "card health", "data-testid": "health" }, h("h2", { text: "Data health" }), indicator,
    h("dl", {}, h("dt", { text: "Session time" }), health.t, h("dt", { text: "Rate" }), health.rate, h("dt", { text: "Device → screen latency p50 / p95" }), health.latency,
      h("dt", { text: "Device → server p50 / p95" }), health.serverLatency,
      h("dt", { text: "Dropped device frames" }), health.input, h("dt", { text: "Dropped batches (this screen)" }), health.client,
      h("dt", { text: "Screens connected" }), health.clients, h("dt", { text: "Samples" }), health.samples,
      h("dt", { text: "Implausible sensor values (ignored)" }), health.implausible,
      h("dt", { text: "Estimator resets / torque faults" }), health.faults, h("dt", { text: "Recording disk" }), health.disk,
      h("dt", { text: "Torque follows (primary estimator)" }), health.primary,
      h("dt", { text: "Failed estimators" }), health.failedEstimators,
      h("dt", { text: "Gait tracking" }), health.tracking,
      h("dt", { text: "IMUs" }), health.imu), conn);
  // switching the primary: a setting (validated, rate-limited and logged by the server)
  const primarySelect = h("select", { id: "primary-select", "data-testid": "primary-select", "aria-label": "Primary estimator" });
  const primaryBtn = h("button", { type: "button", "data-testid": "primary-apply", text: "Switch" });
  const primaryError = errorBox("primary-error");
  primaryBtn.addEventListener("click", () => runAction(primaryBtn, primaryError, async () => {
    const actor = localStorage.getItem("gaitscope.actor") || "clinician";
    const session = await api("PATCH", `/api/sessions/${sessionId}/settings`, { primary: primarySelect.value, actor });
    controls.setSession(session);
  }));
  healthCard.append(h("div", { class: "inline", "data-testid": "primary-switch" },
    h("label", { for: "primary-select", text: "Torque follows " }), primarySelect, primaryBtn), primaryError);

  // --- plots --------------------------------------------------------------------------------------
  const plotsBox = h("div", { class: "plots" });
  const follow = (u, min, max) => (max == null ? [0, WINDOW_S] : [max - WINDOW_S, max]);
  const plots = PLOT_SPECS.map((spec) => {
    const div = h("div", { class: "plot", "data-testid": `plot-${spec.key}` });
    plotsBox.append(div);
    return { spec, div, plot: new Plot(div, { ...spec, xRange: follow }) };
  });
  // desired vs actual speed: shown once a batch says the stack has the intent estimator
  const intentDiv = h("div", { class: "plot", "data-testid": "plot-intent-speed", hidden: true });
  plotsBox.insertBefore(intentDiv, plots[1].div);
  const intentPlot = new Plot(intentDiv, { ...INTENT_SPEC, xRange: follow, plugins: [markersPlugin(() => intentMarks)] });
  const joints = plots.find((p) => p.spec.key === "joints");
  /** The SDRE knee joins the joints plot once a batch says the stack runs `sdre_knee`. */
  function showSdre() {
    if (joints.spec.cols.includes(SDRE_KNEE.col)) return;
    joints.spec = { ...joints.spec, cols: [...joints.spec.cols, SDRE_KNEE.col], series: [...joints.spec.series, SDRE_KNEE.series] };
    joints.plot.setSeries(joints.spec.series);
  }
  // The stack is known (or changed): a ring with a column per estimator phase and the phase plot redrawn.
  function showStack() {
    const failed = new Set(stack.failed.keys());
    health.primary.textContent = stack.primary || "none: the torque is 0";
    health.primary.classList.toggle("warn", !stack.primary);
    health.failedEstimators.textContent = failed.size ? [...stack.failed].map(([n, why]) => `${n}: ${why}`).join("; ") : "none";
    health.failedEstimators.classList.toggle("warn", failed.size > 0);
    // a primary with a stance phase puts it in the gait state: the summary says which phase it shows
    phaseLabel.textContent = STANCE_PHASE.has(stack.primary) ? `Stance phase (${stack.primary})` : "Phase";
    const key = JSON.stringify([stack.names, stack.phased, stack.primary, [...failed]]);
    if (key === stack.key || !stack.phased.length) return; // the plot waits for the first batch's estimators
    const cols = stack.names.map(estColumn);
    if (cols.some((c) => !ring.columns.includes(c))) {
      ring = new Ring(RING_CAPACITY, [...COLUMNS, ...cols]);
      lastT = -Infinity;
    }
    stack.key = key;
    const phase = plots[0];
    phase.plot.destroy();
    phase.div.replaceChildren();
    phase.spec = phaseSpec(stack.names, stack.primary, failed);
    phase.plot = new Plot(phase.div, { ...phase.spec, xRange: follow });
    dataDirty = true;
    const options = stack.phased.filter((n) => !failed.has(n));
    if (JSON.stringify(options) !== JSON.stringify([...primarySelect.options].map((o) => o.value))) {
      primarySelect.replaceChildren(...options.map((n) => h("option", { value: n, text: n })));
    }
    if (stack.primary && options.includes(stack.primary)) primarySelect.value = stack.primary;
  }
  const strideCount = h("span", { class: "hint", "data-testid": "stride-count", text: "waiting for heel strikes…" });
  const bandTorque = h("div", { class: "plot", "data-testid": "overlay-torque" });
  const bandFoot = h("div", { class: "plot", "data-testid": "overlay-foot" });
  // The subject's baseline: the mean stride kept in this browser (per subject code) to compare against.
  const baselineKey = () => `gaitscope.baseline.${subjectCode}`;
  const baselineNote = h("span", { class: "hint", "data-testid": "baseline-note", text: "" });
  const setBaselineBtn = h("button", { type: "button", "data-testid": "set-baseline", text: "Set as baseline" });
  const clearBaselineBtn = h("button", { type: "button", "data-testid": "clear-baseline", text: "Clear baseline" });
  function showBaseline(saved) {
    overlay.setBaseline(saved ? saved.means : null);
    baselineNote.textContent = saved ? `baseline: ${saved.strides} stride${saved.strides === 1 ? "" : "s"} of ${saved.when}` : "no baseline";
    clearBaselineBtn.disabled = !saved;
    strideDirty = true;
  }
  setBaselineBtn.addEventListener("click", () => {
    const means = overlay.snapshot();
    if (!means) {
      baselineNote.textContent = "no complete stride yet";
      return;
    }
    const saved = { means, strides: overlay.count, when: new Date().toLocaleString() };
    localStorage.setItem(baselineKey(), JSON.stringify(saved));
    showBaseline(saved);
  });
  clearBaselineBtn.addEventListener("click", () => {
    localStorage.removeItem(baselineKey());
    showBaseline(null);
  });
  const overlayCard = h("section", { class: "card overlay" },
    h("div", { class: "card-head" }, h("h2", { text: "Per stride: mean ± SD of the last 20" }), strideCount),
    h("div", { class: "overlay-plots" }, bandTorque, bandFoot),
    h("div", { class: "baseline-row" }, setBaselineBtn, clearBaselineBtn, baselineNote));

  // --- controls, events, leg view ------------------------------------------------------------------
  let subjectCode = "";
  const gp = gpLearningCard(sessionId, () => localStorage.getItem("gaitscope.actor") || "clinician");
  const controls = mountControls(sessionId, {
    onEvent: (ev) => addEvents(ev),
    onSession: (s) => {
      title.textContent = `Session ${sessionId} · ${subjectCode || `subject ${s.subject_id}`} · ${s.source.kind} · ${s.state}`;
      gp.setSession(s);
    },
  });
  const eventsCard = h("section", { class: "card", "data-testid": "events-card" }, h("h2", { text: "Events (newest first)" }), events.el);

  const layout = h("div", { class: "page live-page" },
    h("div", { class: "page-head" }, title, h("label", { class: "actor" }, "Acting as ", actorSelect()),
      h("a", { class: "button", href: "#/", text: "← Sessions" })),
    summary, streamError, gp.el, // full width: its three joints side by side
    h("div", { class: "live-grid" },
      h("div", { class: "main-col" }, overlayCard, legView({ session_id: sessionId }), plotsBox),
      h("aside", { class: "side-col" }, healthCard, controls.el, eventsCard)));
  root.append(layout);
  const bands = [
    { c: "torque_Nm", plot: bandPlot(bandTorque, "Torque command", "N·m", COLORS.orange, { line: "#e8a07f", band: "rgba(194,65,12,0.18)" }) },
    { c: "foot_angle_deg", plot: bandPlot(bandFoot, "Foot angle (measured)", "deg", COLORS.blue, { line: "#7fa6d1", band: "rgba(11,92,173,0.18)" }) },
  ];

  // --- stream ---------------------------------------------------------------------------------------
  // device-to-browser latency: the device stamps sent_ns (wall clock, ns); one clock when on this machine
  const recentLatency = [];
  function noteLatency(states) {
    const now = Date.now();
    for (const s of states) if (s.sent_ns != null) recentLatency.push([now, now - s.sent_ns / 1e6]);
    while (recentLatency.length && now - recentLatency[0][0] > 1000) recentLatency.shift();
  }
  function latencyText() {
    if (!recentLatency.length) return "–";
    const v = recentLatency.map((x) => x[1]).sort((a, b) => a - b);
    const q = (p) => v[Math.min(v.length - 1, Math.floor(p * v.length))];
    return `${fmt(q(0.5), 1)} / ${fmt(q(0.95), 1)} ms`;
  }

  function onStates(states, estimators) {
    noteLatency(states);
    const est = estimators || {};
    const phased = Object.keys(est).filter((n) => est[n].columns && est[n].columns.phase);
    if (phased.length && JSON.stringify(phased) !== JSON.stringify(stack.phased)) {
      stack.phased = phased;
      stack.names = phased.filter((n) => !STANCE_PHASE.has(n));
      showStack();
    }
    for (const [n, e] of Object.entries(est)) {
      if (e.failed && !stack.failed.has(n)) {
        stack.failed.set(n, "failed");
        showStack();
      }
    }
    showIntent(est.intent);
    gp.push(states, est[GP_EKF]);
    const intentCols = est.intent && est.intent.columns && est.intent.columns.desired_speed_m_s ? est.intent.columns : null;
    if (intentCols && intentDiv.hidden) intentDiv.hidden = false;
    const sdreKnee = est.sdre_knee && est.sdre_knee.columns ? est.sdre_knee.columns[SDRE_KNEE.col] : null;
    if (sdreKnee) showSdre();
    for (let i = 0; i < states.length; i++) {
      const s = states[i];
      if (s.t < lastT) {
        ring.clear(); // the source restarted (a replay looping): keep time increasing in the window
        lastT = -Infinity;
      }
      lastT = s.t;
      const row = stateRow(s);
      if (intentCols) for (const c of INTENT_SPEC.cols) row[c] = intentValue(intentCols[c] ? intentCols[c][i] : null);
      if (sdreKnee) row[SDRE_KNEE.col] = sdreKnee[i];
      for (const n of stack.names) {
        const v = est[n] && est[n].columns.phase ? est[n].columns.phase[i] : null;
        row[estColumn(n)] = v == null ? null : v * 100;
      }
      ring.push(row);
      if (overlay.push(s.t, row, s.heel_strike)) strideDirty = true;
    }
    if (states.length) {
      lastBatchAt = performance.now();
      dataDirty = true;
    }
  }

  /** The intent estimator's last class (1 speeding up, -1 slowing down, 0 steady), desired speed and confidence. */
  function showIntent(e) {
    if (!e || !e.columns || !e.columns.intent_code) return;
    intentCell.hidden = false;
    const codes = e.columns.intent_code;
    const last = codes.length - 1;
    if (e.failed || last < 0 || codes[last] == null) {
      intentV.textContent = e.failed ? "failed" : "–";
      intentUnit.textContent = "";
      intentCell.dataset.intent = "unknown";
      return;
    }
    const code = codes[last];
    const word = code > 0.5 ? "speeding up" : code < -0.5 ? "slowing down" : "steady";
    intentV.textContent = word;
    intentCell.dataset.intent = word.replace(" ", "-");
    const desired = e.columns.desired_speed_m_s ? e.columns.desired_speed_m_s[last] : null;
    const conf = e.columns.intent_confidence ? e.columns.intent_confidence[last] : null;
    intentUnit.textContent = `desired ${fmt(desired, 2)} m/s · ${fmt(conf, 1)} SD`;
  }

  function onHealth(m) {
    health.rate.textContent = `${fmt(m.rate_hz, 0)} Hz`;
    health.latency.textContent = latencyText();
    health.serverLatency.textContent = `${fmt(m.latency_ms_p50, 1)} / ${fmt(m.latency_ms_p95, 1)} ms`;
    health.input.textContent = String(m.dropped_input);
    health.client.textContent = String(m.dropped_client);
    health.clients.textContent = String(m.clients);
    health.samples.textContent = String(m.samples);
    health.client.classList.toggle("warn", m.dropped_client > 0);
    health.input.classList.toggle("warn", m.dropped_input > 0);
    health.implausible.textContent = String(m.implausible ?? 0);
    health.implausible.classList.toggle("warn", (m.implausible ?? 0) > 0);
    health.faults.textContent = String(m.faults ?? 0);
    health.faults.classList.toggle("warn", (m.faults ?? 0) > 0);
    const disk = { ok: "ok", low: "space low: recording stops when it runs out", critical: "full: recording stopped" }[m.disk ?? "ok"];
    health.disk.textContent = disk;
    health.disk.classList.toggle("warn", (m.disk ?? "ok") !== "ok");
    const tracking = { walking: "walking", standing: "standing still: phase held, torque 0", lost: `lost track, reset: ${m.tracking_note || ""}` }[m.tracking] || "–";
    health.tracking.textContent = tracking;
    health.tracking.classList.toggle("warn", m.tracking === "lost");
    health.imu.textContent = { ok: "ok", fault: m.imu_note }[m.imu] || "–";
    health.imu.classList.toggle("warn", m.imu === "fault");
    if (m.estimators) {
      gp.setStack(m.estimators);
      stack.primary = m.primary ?? null;
      stack.failed = new Map(Object.entries(m.failed_estimators || {}));
      showStack();
    }
  }

  const stream = openSessionStream(sessionId, {
    onMessage(msg) {
      switch (msg.type) {
        case "hello":
          showError(streamError, null);
          subjectCode = msg.subject.code;
          try {
            showBaseline(JSON.parse(localStorage.getItem(baselineKey()) || "null"));
          } catch (err) {
            showBaseline(null); // an unreadable stored baseline is dropped, not fatal
          }
          controls.setSession(msg.session);
          stack.primary = msg.session.settings.primary ?? null; // the health messages then say which drives it
          break;
        case "states":
          onStates(msg.states, msg.estimators);
          break;
        case "health":
          onHealth(msg);
          break;
        case "event":
          addEvents(msg.event);
          if (msg.event.kind === "recording" || msg.event.kind === "system") controls.refreshRecording();
          if (msg.event.field === GP_EKF) gp.onEvent();
          break;
        case "settings":
          controls.setSettings(msg.settings);
          if (msg.settings.primary && !stack.failed.has(msg.settings.primary)) {
            stack.primary = msg.settings.primary; // until the next health message says otherwise
            showStack();
          }
          break;
        default:
          break; // message types this view does not use
      }
    },
    onStatus(status, info) {
      if (status === "open") conn.textContent = "connected";
      else if (status === "connecting") conn.textContent = "connecting…";
      else if (status === "reconnecting") conn.textContent = `connection lost (code ${info.code}); retrying in ${(info.delayMs / 1000).toFixed(1)} s`;
      else if (status === "closed") {
        conn.textContent = "not streaming";
        showError(streamError, `No live data: ${info.reason || `the server closed the stream (code ${info.code})`}.`);
        api("GET", `/api/sessions/${sessionId}`).then((s) => controls.setSession(s)).catch(() => {});
      }
    },
  });

  // --- drawing: at most once per animation frame, whatever the message rate ---------------------------
  function frame(now) {
    raf = requestAnimationFrame(frame);
    if (dataDirty) {
      dataDirty = false;
      for (const { spec, plot } of plots) plot.setData(ring.window("t", spec.cols, WINDOW_S));
      if (!intentDiv.hidden) intentPlot.setData(ring.window("t", INTENT_SPEC.cols, WINDOW_S));
    }
    if (strideDirty) {
      strideDirty = false;
      for (const b of bands) b.plot.setData(overlay.bandData(b.c));
      strideCount.textContent = `${overlay.count} stride${overlay.count === 1 ? "" : "s"}`;
    }
    if (now - lastText > 200) {
      lastText = now;
      const stale = now - lastBatchAt > STALE_MS;
      indicator.textContent = lastBatchAt === 0 ? "NO DATA" : stale ? "STALE" : "LIVE";
      indicator.className = `indicator ${stale ? "stale" : "live"}`;
      // The stream stays open, silent, when another screen stops the session: ask for its state.
      if (stale && now - lastStatePoll > 5000) {
        lastStatePoll = now;
        api("GET", `/api/sessions/${sessionId}`).then((s) => alive && controls.setSession(s)).catch(() => {});
      }
      phaseV.textContent = fmt(ring.last("phase_pct"), 1);
      health.t.textContent = `${fmt(ring.last("t"), 1)} s`;
      const st = overlay.lastStride; // the last complete stride, else the newest sample
      // a stance-phase primary's rate is the stance's, not the stride's: the cadence is then the stride's duration
      const rate = STANCE_PHASE.has(stack.primary) ? (st ? 1 / st.duration : NaN) : st ? st.mean.phase_rate : ring.last("phase_rate");
      const sl = st ? st.mean.stride_length_m : ring.last("stride_length_m");
      cadV.textContent = fmt(60 * rate, 1);
      slV.textContent = fmt(sl, 2);
      spV.textContent = fmt(sl * rate, 2);
      incV.textContent = fmt(st ? st.mean.incline_deg : ring.last("incline_deg"), 1);
      pkV.textContent = fmt(st ? st.peak.torque_Nm : NaN, 1);
    }
    gp.frame(now);
  }
  raf = requestAnimationFrame(frame);

  api("GET", `/api/sessions/${sessionId}/events`).then((evs) => addEvents(...evs)).catch((err) => showError(streamError, err));

  return {
    unmount() {
      alive = false;
      cancelAnimationFrame(raf);
      stream.close();
      for (const p of plots) p.plot.destroy();
      intentPlot.destroy();
      for (const b of bands) b.plot.destroy();
      gp.destroy();
    },
  };
}
