// Live view (`#/sessions/{id}`): the session's stream in plots redrawn once per animation frame, the
// per-stride overlay, data health, controls, events and the 3D leg view. The phase plot overlays the phase
// of every estimator of the session's stack (the primary, which drives the torque, drawn widest). A stack with
// the speed-change intent estimator (seed 001) adds its desired vs actual speed, its detections marked. The
// hip and knee flexion come from the gait state's thigh and shank angles (sensed, or derived from raw IMUs by
// the stack's front ends); a stack with the SDRE estimator (`sdre_knee`, seed 002) adds its knee, dashed. A stack
// with the GP-EKF (`gp_ekf`, seed 003) gets its card (`gp_learning.js`): its phase is the STANCE phase, plotted
// there and kept out of the gait-phase plot.
//
// Layout (issue #12): panels in a grid (`live_layout.js`: which, their order and width, remembered per logged-in
// user), the key plots (phase, torque, phase rate, incline) first, in view without scrolling at 1440x900; on
// a phone the data health and the stop control come first. The time plots are one `PlotGroup`: pause and
// resume (data keeps arriving), zoom and pan a paused view, linked cursors with hover values, the setting
// changes and annotations as labelled markers. A new connection gets the session's last 30 s first (the
// server's history), so the plots open full. The health box judges the figures (`live_health.js`); the stream
// reconnects by itself, at once when the server is back, and says what happened to a session that ended.

import { openSessionStream } from "./api.js";
import * as api from "./api_client.js";
import { currentUser, fence } from "./auth.js";
import { mountControls } from "./controls.js";
import { deviceCredentialsCard } from "./device_credentials.js";
import { INTENT, STANCE_PHASE } from "./estimators.js";
import { describeEvent, EVENT_COLORS, EventList, isSettingChange } from "./events.js";
import { GP_EKF, gpLearningCard } from "./gp_learning.js";
import { legView } from "./leg_view.js";
import { HealthBox } from "./live_health_box.js";
import { PanelLayout } from "./live_layout.js";
import { EstimatorPlots } from "./live_estimator_plots.js";
import { sessionEndBanner } from "./live_session_end.js";
import { COLORS, Plot, PlotGroup, Ring, StrideOverlay } from "./plots.js";
import { onServerChange } from "./server_status.js";
import { errorBox, fmt, h, runAction, showError } from "./ui.js";
import { ESTIMATORS } from "./wire.js";

export const WINDOW_S = 10; // seconds of full-rate history the live plots show
const RING_CAPACITY = 2048; // > 10 s at the 60 Hz the stream is asked for (34 s), bounded memory
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

/** The intent estimator's plot as its descriptor states it (wire.js), or null when none is registered. */
const INTENT_PLOT = INTENT ? ESTIMATORS[INTENT].plots[0] : null;

/**
 * The speed-change intent estimator's (`INTENT`, seed 001) desired and actual speed, as its descriptor's plot
 * hint states it; `review.js` uses it too. Both hold between mid-stances (twice per step), where the filter updates
 * them; 0 before its first one.
 */
export const INTENT_SPEC = {
  key: INTENT_PLOT ? INTENT_PLOT.key : "intent-none", title: INTENT_PLOT ? INTENT_PLOT.title : "",
  yLabel: INTENT_PLOT ? INTENT_PLOT.y_label : "", cols: INTENT_PLOT ? [...INTENT_PLOT.outputs] : [],
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

/** The SDRE knee estimator (its descriptor's quantity `knee_angle`: seed 002's), or null. */
const SDRE = Object.keys(ESTIMATORS).find((n) => Object.values(ESTIMATORS[n].quantities).includes("knee_angle")) || null;

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

/** The key plots, first and in view at 1440x900; the rest go in the "more plots" panel. */
const KEY_PLOTS = ["phase", "torque", "phase_rate", "incline"];
const KEY_HEIGHT = 180;

export function mountLive(root, sessionId) {
  let ring = new Ring(RING_CAPACITY, COLUMNS);
  // the session's estimators with a gait phase (known from the first batch; `phased`: with any phase, the
  // primary's choices), the one driving the torque, failures
  const stack = { names: [], phased: [], primary: null, failed: new Map(), key: "" };
  const overlay = new StrideOverlay(["torque_Nm", "foot_angle_deg", "phase_rate", "stride_length_m", "incline_deg"]);
  const events = new EventList("events-list");
  const group = new PlotGroup({ pauseOnZoom: true });
  let lastT = -Infinity;
  let dataDirty = false;
  let strideDirty = false;
  let lastText = 0;
  let raf = 0;
  let lastStatePoll = performance.now();
  let alive = true;
  let helloWall = 0; // Date.now() at the last hello: states the server had before it are the history
  let serverLost = false; // the page lost the server since the stream last opened
  let ended = false;

  // --- header, summary, health --------------------------------------------------------------------
  const title = h("h1", { "data-testid": "live-title", text: `Session ${sessionId}` });
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

  const healthBox = new HealthBox();
  const health = healthBox.f;
  // switching the primary: a setting (validated, rate-limited and logged by the server)
  const primarySelect = h("select", { id: "primary-select", "data-testid": "primary-select", "aria-label": "Primary estimator" });
  const primaryBtn = h("button", { type: "button", "data-testid": "primary-apply", text: "Switch" });
  const primaryError = errorBox("primary-error");
  primaryBtn.addEventListener("click", () => runAction(primaryBtn, primaryError, async () => {
    const session = await api.changeSettings(sessionId, { primary: primarySelect.value });
    controls.setSession(session);
  }));
  healthBox.el.append(fence(h("div", { class: "inline", "data-testid": "primary-switch" },
    h("label", { for: "primary-select", text: "Torque follows " }), primarySelect, primaryBtn), "assist",
  "Only a clinician or an admin switches the estimator driving the torque."), primaryError);

  // --- plots: one group (shared zoom, cursor, markers, pause) ----------------------------------------
  const follow = (u, min, max) => (max == null ? [0, WINDOW_S] : [max - WINDOW_S, max]);
  const keyBox = h("div", { class: "plots key-plots" });
  const moreBox = h("div", { class: "plots more-plots" });
  const plotOf = (spec) => new Plot(spec.div, { ...spec.spec, xRange: follow, group, height: spec.height });
  const plots = PLOT_SPECS.map((spec) => {
    const key = KEY_PLOTS.includes(spec.key);
    const div = h("div", { class: "plot", "data-testid": `plot-${spec.key}` });
    const entry = { spec, div, height: key ? KEY_HEIGHT : 170 };
    entry.plot = new Plot(div, { ...spec, xRange: follow, group, height: entry.height });
    return entry;
  });
  for (const k of KEY_PLOTS) keyBox.append(plots.find((p) => p.spec.key === k).div);
  for (const p of plots) if (!KEY_PLOTS.includes(p.spec.key)) moreBox.append(p.div);
  // desired vs actual speed: shown once a batch says the stack has the intent estimator
  const intentDiv = h("div", { class: "plot", "data-testid": "plot-intent-speed", hidden: true });
  moreBox.prepend(intentDiv);
  const intentPlot = new Plot(intentDiv, { ...INTENT_SPEC, xRange: follow, group });
  // the plots other estimators' descriptors ask for, as their estimators appear in the stream
  const estimatorPlots = new EstimatorPlots(moreBox, { group, xRange: follow, seconds: WINDOW_S, except: INTENT ? [INTENT] : [] });
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
    phase.plot = plotOf(phase);
    dataDirty = true;
    const options = stack.phased.filter((n) => !failed.has(n));
    if (JSON.stringify(options) !== JSON.stringify([...primarySelect.options].map((o) => o.value))) {
      primarySelect.replaceChildren(...options.map((n) => h("option", { value: n, text: n })));
    }
    if (stack.primary && options.includes(stack.primary)) primarySelect.value = stack.primary;
  }

  // pause / resume (the data keeps arriving; resuming catches up), and the paused view's zoom and pan
  const pauseBtn = h("button", { type: "button", class: "primary", "data-testid": "live-pause", text: "Pause",
    title: "Pause the plots (the data keeps arriving); Resume catches up", "aria-pressed": "false" });
  const pauseNote = h("span", { class: "hint", "data-testid": "live-pause-note", "aria-live": "polite",
    text: "Following the newest 10 s. Drag across a plot or use the wheel to zoom (it pauses)." });
  pauseBtn.addEventListener("click", () => (group.paused ? group.resume() : group.pause()));
  group.onChange((g) => {
    pauseBtn.textContent = g.paused ? "Resume" : "Pause";
    pauseBtn.setAttribute("aria-pressed", String(g.paused));
    pauseNote.textContent = g.paused
      ? "Paused: the data keeps arriving. Drag or wheel to zoom, Shift+drag to pan; Resume catches up."
      : "Following the newest 10 s. Drag across a plot or use the wheel to zoom (it pauses).";
  });
  /** Setting changes and annotations as labelled markers on every time plot; detected intents on their plot. */
  function showMarkers() {
    const all = [...events.events.values()];
    group.setMarkers(all.filter((e) => isSettingChange(e) || e.kind === "annotation")
      .map((e) => ({ t: e.t, label: describeEvent(e).short, kind: e.kind })));
    intentPlot.setMarkers(all.filter((e) => e.kind === "intent")
      .map((e) => ({ t: e.t, label: describeEvent(e).short, kind: "intent", color: EVENT_COLORS.intent })));
    const settings = all.filter(isSettingChange).sort((a, b) => a.t - b.t || a.id - b.id);
    controls.setLastChange(settings.length ? settings[settings.length - 1] : null);
  }
  const addEvents = (...evs) => {
    events.add(...evs);
    showMarkers();
  };

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

  // --- controls, events, leg view, panels ------------------------------------------------------------
  let subjectCode = "";
  const sessionEnd = sessionEndBanner();
  const gp = gpLearningCard(sessionId);
  const credentials = deviceCredentialsCard(sessionId);
  const controls = mountControls(sessionId, {
    onEvent: (ev) => addEvents(ev),
    onSession: (s) => {
      title.textContent = `Session ${sessionId} · ${subjectCode || `subject ${s.subject_id}`} · ${s.source.kind} · ${s.state}`;
      gp.setSession(s);
      credentials.setSession(s);
      group.setContext({ max_torque_Nm: s.settings.max_torque_Nm });
      if (s.state === "running") sessionEnd.hide();
    },
  });
  const card = (id, heading, ...body) => h("section", { class: "card", "data-testid": `${id}-card` }, h("h2", { text: heading }), ...body);
  const panels = [
    { id: "key-plots", title: "Key plots", size: 2, el: card("key-plots", "Phase, torque, phase rate, incline",
      h("div", { class: "live-tools" }, pauseNote), keyBox) },
    { id: "summary", title: "Summary figures", size: 1, el: summary },
    { id: "health", title: "Data health", size: 1, el: healthBox.el },
    { id: "session", title: "Session (start, stop)", size: 1, el: controls.cards.session },
    { id: "settings", title: "Assistance settings", size: 1, el: controls.cards.settings },
    { id: "overlays", title: "Per-stride overlays", size: 2, el: h("section", { class: "card overlay" },
      h("div", { class: "card-head" }, h("h2", { text: "Per stride: mean ± SD of the last 20" }), strideCount),
      h("div", { class: "overlay-plots" }, bandTorque, bandFoot),
      h("div", { class: "baseline-row" }, setBaselineBtn, clearBaselineBtn, baselineNote)) },
    { id: "events", title: "Events", size: 1, el: card("events", "Events (newest first)", events.el) },
    { id: "more-plots", title: "More plots", size: 2, el: card("more-plots", "Stride length, foot, shank, hip and knee", moreBox) },
    { id: "annotation", title: "Annotation", size: 1, el: controls.cards.annotation },
    { id: "recording", title: "Recording", size: 1, el: controls.cards.recording },
    { id: "leg", title: "3D leg view", size: 1, el: legView({ session_id: sessionId }) },
    { id: "imu", title: "IMU calibration", size: 1, el: controls.cards.imu },
    { id: "gp", title: "GP-EKF learning", size: 3, el: gp.el },
    { id: "credentials", title: "Device credentials", size: 1, el: credentials.el },
  ];
  const layout = new PanelLayout(panels, currentUser().name);
  const page = h("div", { class: "page live-page" },
    h("div", { class: "page-head" }, title, pauseBtn, layout.menu, h("a", { class: "button", href: "#/", text: "← Sessions" })),
    streamError, sessionEnd.el, layout.grid);
  root.append(page);
  const bands = [
    { c: "torque_Nm", plot: bandPlot(bandTorque, "Torque command", "N·m", COLORS.orange, { line: "#e8a07f", band: "rgba(194,65,12,0.18)" }) },
    { c: "foot_angle_deg", plot: bandPlot(bandFoot, "Foot angle (measured)", "deg", COLORS.blue, { line: "#7fa6d1", band: "rgba(11,92,173,0.18)" }) },
  ];

  // --- stream ---------------------------------------------------------------------------------------
  function onStates(states, estimators) {
    // the history the server sends on connecting (received before the hello): plotted, not live
    const history = states.length > 0 && states[states.length - 1].recv_ns / 1e6 < helloWall - 50;
    if (!history) healthBox.noteStates(states);
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
    const intentEst = INTENT ? est[INTENT] : undefined;
    showIntent(intentEst);
    gp.push(states, est[GP_EKF]);
    estimatorPlots.push(states, est);
    const intentCols = intentEst && intentEst.columns && intentEst.columns[INTENT_SPEC.cols[0]] ? intentEst.columns : null;
    if (intentCols && intentDiv.hidden) intentDiv.hidden = false;
    const sdreKnee = SDRE && est[SDRE] && est[SDRE].columns ? est[SDRE].columns[SDRE_KNEE.col] : null;
    if (sdreKnee) showSdre();
    for (let i = 0; i < states.length; i++) {
      const s = states[i];
      if (s.t <= lastT) {
        if (history || s.t === lastT) continue; // already shown: a reconnection's history overlaps what the page has
        ring.clear(); // the source restarted (a replay looping): keep time increasing in the window
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
    if (states.length) dataDirty = true;
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
    healthBox.onHealth(m);
    if (m.estimators) {
      gp.setStack(m.estimators);
      stack.primary = m.primary ?? null;
      stack.failed = new Map(Object.entries(m.failed_estimators || {}));
      showStack();
    }
  }

  /** The session is not running (anymore): what happened, and the way to start again. */
  async function checkEnded() {
    try {
      const [s, evs] = await Promise.all([api.getSession(sessionId), api.sessionEvents(sessionId)]);
      if (!alive) return;
      controls.setSession(s);
      addEvents(...evs);
      if (s.state === "stopped" || s.state === "failed") {
        ended = true;
        healthBox.ended = true;
        sessionEnd.show(s, evs, serverLost);
        healthBox.setConnection("not streaming: the session is not running", false);
      }
    } catch (err) {
      if (alive) showError(streamError, err);
    }
  }

  const handlers = {
    /** @param {import("./wire.js").BrowserMessage} msg */
    onMessage(msg) {
      switch (msg.type) {
        case "hello":
          helloWall = Date.now();
          serverLost = false;
          showError(streamError, null);
          subjectCode = msg.subject.code;
          healthBox.declaredHz = msg.source_rate_hz;
          try {
            showBaseline(JSON.parse(localStorage.getItem(baselineKey()) || "null"));
          } catch {
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
          group.setContext({ max_torque_Nm: msg.settings.max_torque_Nm });
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
      if (status === "open") healthBox.setConnection("connected", true);
      else if (status === "connecting") healthBox.setConnection("connecting…", false);
      else if (status === "reconnecting") {
        if (info.code === 1006) serverLost = true; // the connection failed or dropped: the server may be gone
        healthBox.setConnection(`connection lost (code ${info.code}); retrying in ${(info.delayMs / 1000).toFixed(1)} s`, false);
      } else if (status === "closed") {
        healthBox.setConnection("not streaming", false);
        showError(streamError, `No live data: ${info.reason || `the server closed the stream (code ${info.code})`}.`);
        checkEnded().then(() => ended && showError(streamError, null));
      }
    },
  };
  let stream = openSessionStream(sessionId, handlers);
  // The header's health check saw the server come back: reconnect now rather than at the next back-off.
  const stopWatching = onServerChange((d) => {
    if (d.state === "lost") serverLost = true;
    if (d.state === "back" && alive && !ended && !healthBox.connected) {
      stream.close();
      stream = openSessionStream(sessionId, handlers);
    }
  });

  // --- drawing: at most once per animation frame, whatever the message rate ---------------------------
  function frame(now) {
    raf = requestAnimationFrame(frame);
    if (dataDirty) {
      dataDirty = false;
      for (const { spec, plot } of plots) plot.setData(ring.window("t", spec.cols, WINDOW_S));
      if (!intentDiv.hidden) intentPlot.setData(ring.window("t", INTENT_SPEC.cols, WINDOW_S));
      estimatorPlots.draw();
    }
    if (strideDirty) {
      strideDirty = false;
      for (const b of bands) b.plot.setData(overlay.bandData(b.c));
      strideCount.textContent = `${overlay.count} stride${overlay.count === 1 ? "" : "s"}`;
    }
    if (now - lastText > 200) {
      lastText = now;
      const verdict = healthBox.update(now, ring.last("t"));
      controls.editor.clampSliders(now);
      // The stream stays open, silent, when another screen stops the session: ask for its state.
      if (!verdict.live && !ended && healthBox.connected && now - lastStatePoll > 5000) {
        lastStatePoll = now;
        api.getSession(sessionId).then((s) => {
          if (!alive) return;
          controls.setSession(s);
          if (s.state !== "running" && s.state !== "created") checkEnded();
        }).catch(() => {});
      }
      // what the key plots span and where each plot drew its markers, readable from the page (the e2e tests)
      const shown = ring.window("t", [], WINDOW_S)[0];
      keyBox.dataset.shownS = shown.length ? (shown[shown.length - 1] - shown[0]).toFixed(1) : "0";
      for (const p of [...plots, { div: intentDiv, plot: intentPlot }]) {
        const marks = JSON.stringify(p.plot.drawnMarkers.map((m) => [m.label, Math.round(m.x), m.row]));
        if (p.div.dataset.markers !== marks) p.div.dataset.markers = marks;
      }
      phaseV.textContent = fmt(ring.last("phase_pct"), 1);
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

  api.sessionEvents(sessionId).then((evs) => addEvents(...evs)).catch((err) => showError(streamError, err));

  return {
    unmount() {
      alive = false;
      cancelAnimationFrame(raf);
      stopWatching();
      stream.close();
      for (const p of plots) p.plot.destroy();
      intentPlot.destroy();
      estimatorPlots.destroy();
      for (const b of bands) b.plot.destroy();
      gp.destroy();
    },
  };
}
