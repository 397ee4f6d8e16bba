// The live view's time plots (live.js): the gait-state plots (the key plots, then the "more plots"), the
// speed-change intent's desired vs actual speed, the plots other estimators' descriptors ask for
// (live_estimator_plots.js), one `PlotGroup` with pause and resume, over a ring of the last seconds of the
// stream; the phase plot overlays the phase of every estimator of the stack. The gait-state plots' specs and
// the intent's are the review's too (review_plots.js).

import { estimatorLabel, INTENT, STANCE_PHASE } from "./estimators.js";
import { describeEvent, EVENT_COLORS, isSettingChange } from "./events.js";
import { EstimatorPlots } from "./live_estimator_plots.js";
import { COLORS, Plot, Ring } from "./plots.js";
import { h } from "./ui.js";
import { ESTIMATORS } from "./wire.js";

export const WINDOW_S = 10; // seconds of full-rate history the live plots show
const RING_CAPACITY = 2048; // > 10 s at the 60 Hz the stream is asked for (34 s), bounded memory
const COLUMNS = ["t", "phase_pct", "tbe_pct", "phase_rate", "incline_deg", "stride_length_m", "torque_Nm",
  "foot_angle_deg", "foot_pred_deg", "shank_angle_deg", "shank_pred_deg", "desired_speed_m_s", "speed_m_s",
  "hip_flex_deg", "knee_flex_deg", "knee_sdre_deg"];

/** The plots of a gait-state series; `review_plots.js` uses the same list. */
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
export const SDRE_KNEE = { col: "knee_sdre_deg", series: { label: "knee, SDRE from IMUs", color: COLORS.orange, dash: [6, 4] } };

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
 * hint states it; `review_plots.js` uses it too. Both hold between mid-stances (twice per step), where the filter updates
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
  // null (not estimated) stays null: a gap, never 0 % (issue #23)
  return { ...s, phase_pct: s.phase == null ? null : s.phase * 100, tbe_pct: s.tbe_phase == null ? null : s.tbe_phase * 100, hip_flex_deg: s.thigh_angle_deg,
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
  // names on screen: the descriptors' labels (issue #23), never the machine names
  const label = (n) => `${estimatorLabel(n)}${n === primary ? " (primary: drives the torque)" : ""}${failed.has(n) ? " (failed)" : ""}`;
  const title = !primary ? "Phase of every estimator; no primary: torque 0"
    : STANCE_PHASE.has(primary) ? `Gait phase of every estimator; the torque follows ${estimatorLabel(primary)}'s stance phase (its card)`
      : `Phase of every estimator; the torque follows ${estimatorLabel(primary)}`;
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
const KEY_HEIGHT = 260;

/**
 * The live view's time plots and the ring they draw from.
 * @param {import("./plots.js").PlotGroup} group the plots' group (shared zoom, cursor, markers, pause)
 */
export class LivePlots {
  constructor(group) {
    this.group = group;
    this.ring = new Ring(RING_CAPACITY, COLUMNS);
    this.lastT = -Infinity; // the newest sample's time
    this.dirty = false; // samples arrived since the last draw
    const follow = (u, min, max) => (max == null ? [0, WINDOW_S] : [max - WINDOW_S, max]);
    this._plotOf = (entry) => new Plot(entry.div, { ...entry.spec, xRange: follow, group, height: entry.height });
    this.keyBox = h("div", { class: "plots key-plots" });
    this.moreBox = h("div", { class: "plots more-plots" });
    this.plots = PLOT_SPECS.map((spec) => {
      const key = KEY_PLOTS.includes(spec.key);
      const div = h("div", { class: "plot", "data-testid": `plot-${spec.key}` });
      const entry = { spec, div, height: key ? KEY_HEIGHT : 170 };
      entry.plot = new Plot(div, { ...spec, xRange: follow, group, height: entry.height });
      return entry;
    });
    for (const k of KEY_PLOTS) this.keyBox.append(this.plots.find((p) => p.spec.key === k).div);
    for (const p of this.plots) if (!KEY_PLOTS.includes(p.spec.key)) this.moreBox.append(p.div);
    // desired vs actual speed: shown once a batch says the stack has the intent estimator
    this.intentDiv = h("div", { class: "plot", "data-testid": "plot-intent-speed", hidden: true });
    this.moreBox.prepend(this.intentDiv);
    this.intentPlot = new Plot(this.intentDiv, { ...INTENT_SPEC, xRange: follow, group });
    // the plots other estimators' descriptors ask for, as their estimators appear in the stream
    this.estimatorPlots = new EstimatorPlots(this.moreBox, { group, xRange: follow, seconds: WINDOW_S, except: INTENT ? [INTENT] : [] });
    this.joints = this.plots.find((p) => p.spec.key === "joints");

    // pause / resume (the data keeps arriving; resuming catches up), and the paused view's zoom and pan
    this.pauseBtn = h("button", { type: "button", class: "primary", "data-testid": "live-pause", text: "Pause",
      title: "Pause the plots (the data keeps arriving); Resume catches up", "aria-pressed": "false" });
    this.pauseNote = h("span", { class: "hint", "data-testid": "live-pause-note", "aria-live": "polite",
      text: "Following the newest 10 s. Drag across a plot or use the wheel to zoom (it pauses)." });
    this.pauseBtn.addEventListener("click", () => (group.paused ? group.resume() : group.pause()));
    group.onChange((g) => {
      this.pauseBtn.textContent = g.paused ? "Resume" : "Pause";
      this.pauseBtn.setAttribute("aria-pressed", String(g.paused));
      this.pauseNote.textContent = g.paused
        ? "Paused: the data keeps arriving. Drag or wheel to zoom, Shift+drag to pan; Resume catches up."
        : "Following the newest 10 s. Drag across a plot or use the wheel to zoom (it pauses).";
    });
  }

  /** The SDRE knee joins the joints plot once a batch says the stack runs `sdre_knee`. */
  showSdre() {
    const joints = this.joints;
    if (joints.spec.cols.includes(SDRE_KNEE.col)) return;
    joints.spec = { ...joints.spec, cols: [...joints.spec.cols, SDRE_KNEE.col], series: [...joints.spec.series, SDRE_KNEE.series] };
    joints.plot.setSeries(joints.spec.series);
  }

  /**
   * The stack is known (or changed): a ring with a column per estimator phase and the phase plot drawn again.
   * @param {string[]} names @param {string | null} primary @param {Set<string>} failed
   */
  setStack(names, primary, failed) {
    const cols = names.map(estColumn);
    if (cols.some((c) => !this.ring.columns.includes(c))) {
      this.ring = new Ring(RING_CAPACITY, [...COLUMNS, ...cols]);
      this.lastT = -Infinity;
    }
    const phase = this.plots[0];
    phase.plot.destroy();
    phase.div.replaceChildren();
    phase.spec = phaseSpec(names, primary, failed);
    phase.plot = this._plotOf(phase);
    this.dirty = true;
  }

  /**
   * A batch of states and the estimators' outputs into the ring.
   * @param {Array<Record<string, any>>} states @param {Record<string, any>} est a batch's `estimators`
   * @param {boolean} history the history the server sends on connecting
   * @param {string[]} names the stack's estimators with a gait phase (the phase plot's)
   * @param {(s: Record<string, any>, row: Record<string, any>) => void} onRow each row kept (the stride overlay's)
   */
  push(states, est, history, names, onRow) {
    this.estimatorPlots.push(states, est);
    const intentEst = INTENT ? est[INTENT] : undefined;
    const intentCols = intentEst && intentEst.columns && intentEst.columns[INTENT_SPEC.cols[0]] ? intentEst.columns : null;
    if (intentCols && this.intentDiv.hidden) this.intentDiv.hidden = false;
    const sdreKnee = SDRE && est[SDRE] && est[SDRE].columns ? est[SDRE].columns[SDRE_KNEE.col] : null;
    if (sdreKnee) this.showSdre();
    for (let i = 0; i < states.length; i++) {
      const s = states[i];
      if (s.t <= this.lastT) {
        if (history || s.t === this.lastT) continue; // already shown: a reconnection's history overlaps what the page has
        this.ring.clear(); // the source restarted (a replay looping): keep time increasing in the window
      }
      this.lastT = s.t;
      const row = stateRow(s);
      if (intentCols) for (const c of INTENT_SPEC.cols) row[c] = intentValue(intentCols[c] ? intentCols[c][i] : null);
      if (sdreKnee) row[SDRE_KNEE.col] = sdreKnee[i];
      for (const n of names) {
        const v = est[n] && est[n].columns.phase ? est[n].columns.phase[i] : null;
        row[estColumn(n)] = v == null ? null : v * 100;
      }
      this.ring.push(row);
      onRow(s, row);
    }
    if (states.length) this.dirty = true;
  }

  /** Setting changes and annotations as labelled markers on every time plot; detected intents on their plot. */
  setMarkers(events) {
    this.group.setMarkers(events.filter((e) => isSettingChange(e) || e.kind === "annotation")
      .map((e) => ({ t: e.t, label: describeEvent(e).short, kind: e.kind })));
    this.intentPlot.setMarkers(events.filter((e) => e.kind === "intent")
      .map((e) => ({ t: e.t, label: describeEvent(e).short, kind: "intent", color: EVENT_COLORS.intent })));
  }

  /** The newest value of ring column `col`. */
  last(col) {
    return this.ring.last(col);
  }

  /** Every plot's data drawn again, when samples arrived since the last draw. */
  draw() {
    if (!this.dirty) return;
    this.dirty = false;
    for (const { spec, plot } of this.plots) plot.setData(this.ring.window("t", spec.cols, WINDOW_S));
    if (!this.intentDiv.hidden) this.intentPlot.setData(this.ring.window("t", INTENT_SPEC.cols, WINDOW_S));
    this.estimatorPlots.draw();
  }

  /** What the key plots span, where each plot drew its markers and its y range, readable from the page (the e2e tests). */
  readouts() {
    const shown = this.ring.window("t", [], WINDOW_S)[0];
    this.keyBox.dataset.shownS = shown.length ? (shown[shown.length - 1] - shown[0]).toFixed(1) : "0";
    for (const p of [...this.plots, { div: this.intentDiv, plot: this.intentPlot }]) {
      const marks = JSON.stringify(p.plot.drawnMarkers.map((m) => [m.label, Math.round(m.x), m.row]));
      if (p.div.dataset.markers !== marks) p.div.dataset.markers = marks;
      const y = p.plot.u.scales.y;
      const range = y.min == null || y.max == null ? "" : `${+y.min.toFixed(3)},${+y.max.toFixed(3)}`;
      if (p.div.dataset.yRange !== range) p.div.dataset.yRange = range;
    }
  }

  destroy() {
    for (const p of this.plots) p.plot.destroy();
    this.intentPlot.destroy();
    this.estimatorPlots.destroy();
  }
}
