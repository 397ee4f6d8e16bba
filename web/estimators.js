// The estimators of a review's re-run: the picker (which of them to run on this trial) and how each one's
// outputs are overlaid on the review plots (its own colour and dash, a legend entry naming it). An estimator is
// shown by its descriptor's label, never by its machine name (issue #23: one vocabulary).
// What is registered comes from the generated wire.js (sessions/registry.py); what can run on a trial
// from `GET /api/trials/{id}/estimators` (RerunChoices). The server stays the judge (422 with a reason).

import { errorBox, h, showError } from "./ui.js";
import { ESTIMATORS } from "./wire.js";

const NAMES = Object.keys(ESTIMATORS); // registry order: the order a stack runs them in

/** Overlay styles by registry index (stable across re-runs); dashes tell them apart without colour. */
const STYLES = [
  { color: "#111827" }, // hs_detector: heel strikes as dots
  { color: "#be185d" }, // phase_ekf
  { color: "#0e7490", dash: [9, 4] }, // tbe
  { color: "#a16207", dash: [3, 3] }, // hs_backup
  { color: "#4338ca", dash: [12, 4, 3, 4] },
  { color: "#4d7c0f", dash: [6, 3, 6, 8] },
];

/** The name on screen of an estimator (its registry name when it is not registered). */
export function estimatorLabel(name) {
  return ESTIMATORS[name] ? ESTIMATORS[name].label : name;
}

/** `{color, dash}` of an estimator's overlay. */
export function estimatorStyle(name) {
  const i = NAMES.indexOf(name);
  return STYLES[(i < 0 ? NAMES.length : i) % STYLES.length];
}

/** Which outputs are overlaid on which review plot (`PLOT_SPECS` key), and how they read there. */
/** @type {Array<{output: string, plot: string, what: string, scale?: number}>} */
const OVERLAID = [
  { output: "phase", plot: "phase", what: "phase", scale: 100 },
  { output: "phase_rate", plot: "phase_rate", what: "phase rate" },
  { output: "stride_length_m", plot: "stride_length", what: "stride length" },
  { output: "incline_deg", plot: "incline", what: "incline" },
  { output: "knee_sdre_deg", plot: "joints", what: "knee" },
];

/** Estimators whose `phase` and `phase_rate` are of STANCE (0 at heel strike, 1 at toe-off: seed 003's GP-EKF),
 * not of the gait cycle (their descriptors' quantity `stance_phase`): kept off the gait-phase and phase-rate plots,
 * where they would read as gait phase. */
export const STANCE_PHASE = new Set(NAMES.filter((n) => ESTIMATORS[n].quantities.phase === "stance_phase"));

/** The estimator that learns a model online (its descriptor's `learned_model`: seed 003's GP-EKF), or null. */
export const LEARNER = NAMES.find((n) => ESTIMATORS[n].learned_model) || null;

/** The speed-change intent estimator (the one estimating the desired speed: seed 001's), or null. */
export const INTENT = NAMES.find((n) => Object.values(ESTIMATORS[n].quantities).includes("desired_speed")) || null;

/**
 * The name on screen of the model an estimator learns online: setting events whose field is that estimator's
 * name carry the model's versions. Null for any other field.
 * @param {string} field
 * @returns {string | null}
 */
export function learnedModel(field) {
  return Object.hasOwn(ESTIMATORS, field) ? ESTIMATORS[field].learned_model : null;
}

/**
 * The registered gait-fingerprint filters of these variants (seed 004), in registry order.
 * @param {...("average" | "personal" | "online")} roles
 */
export function fingerprintEstimators(...roles) {
  return NAMES.filter((n) => roles.includes(ESTIMATORS[n].fingerprint));
}

const hasPhase = (name) => ESTIMATORS[name] !== undefined && "phase" in ESTIMATORS[name].outputs;

/** "a", "a and b", "a, b and c" (or another conjunction). */
export function listText(items, conjunction = "and") {
  return items.length < 2 ? items.join("") : `${items.slice(0, -1).join(", ")} ${conjunction} ${items[items.length - 1]}`;
}

/**
 * The estimators a re-run response holds (its `<name>.<output>` columns), in registry order.
 * @param {Record<string, unknown[]>} res
 */
export function rerunEstimators(res) {
  const found = new Set(Object.keys(res).filter((k) => k.includes(".")).map((k) => k.slice(0, k.indexOf("."))));
  return [...NAMES.filter((n) => found.has(n)), ...[...found].filter((n) => !NAMES.includes(n)).sort()];
}

/**
 * The overlay of a re-run's estimators: per plot key its series (`{label, color, dash, points?, col}`),
 * the columns they draw (in the plot's unit), and per estimator what it draws (for the legend). An
 * estimator without a phase shows its heel strikes as dots at 0 % on the phase plot.
 * @param {string[]} names @param {Record<string, any[]>} res columns: numbers (booleans for heel strikes)
 */
export function estimatorOverlay(names, res) {
  const series = {};
  const cols = {};
  const drawn = {};
  for (const name of names) {
    const label = `${estimatorLabel(name)}, re-run`;
    const style = estimatorStyle(name);
    drawn[name] = [];
    const add = (plot, col, values, what, extra = {}) => {
      (series[plot] ||= []).push({ label, color: style.color, dash: style.dash, width: 2, col, ...extra });
      cols[col] = values;
      drawn[name].push(what);
    };
    for (const o of OVERLAID) {
      if (STANCE_PHASE.has(name) && (o.output === "phase" || o.output === "phase_rate")) continue;
      const values = res[`${name}.${o.output}`];
      if (!values) continue;
      add(o.plot, `${name}.${o.output}`, o.scale ? values.map((v) => (v == null ? null : v * o.scale)) : values, o.what);
    }
    const strikes = res[`${name}.heel_strike`];
    if (strikes && !hasPhase(name)) {
      add("phase", `${name}.heel_strike`, strikes.map((v) => (v ? 0 : null)), "heel strikes (dots at 0 %)",
        { points: true, value: (u, v) => (v == null ? "–" : "heel strike") });
    }
  }
  return { series, cols, drawn };
}

/** A line sample in an estimator's colour and dash (or a dot), for a legend. */
function swatch(name, dot) {
  const ns = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("viewBox", "0 0 36 12");
  svg.setAttribute("class", "swatch");
  svg.setAttribute("aria-hidden", "true");
  const style = estimatorStyle(name);
  const mark = document.createElementNS(ns, dot ? "circle" : "line");
  if (dot) Object.entries({ cx: 18, cy: 6, r: 5, fill: style.color }).forEach(([k, v]) => mark.setAttribute(k, String(v)));
  else {
    Object.entries({ x1: 0, y1: 6, x2: 36, y2: 6, stroke: style.color, "stroke-width": 3 }).forEach(([k, v]) => mark.setAttribute(k, String(v)));
    if (style.dash) mark.setAttribute("stroke-dasharray", style.dash.join(" "));
  }
  svg.append(mark);
  return svg;
}

/** The legend of an overlay: one entry per estimator, what it draws, in its colour. */
export function overlayLegend(el, names, drawn) {
  el.replaceChildren(...names.map((n) => h("li", { "data-testid": "rerun-legend-entry", "data-estimator": n },
    swatch(n, !hasPhase(n)), h("span", { class: "estimator-text" }, h("span", { class: "label", text: estimatorLabel(n) }),
      h("span", { class: "hint", text: drawn[n] && drawn[n].length ? drawn[n].join(", ") : "nothing to plot" })))));
  el.hidden = !names.length;
}

/**
 * The re-run card's estimator picker: one checkbox per estimator that can run on the trial (its recorded
 * stack checked), the others shown disabled with why. `onChange` runs on every change of the choice.
 */
export class EstimatorPicker {
  constructor(onChange) {
    this.onChange = onChange;
    this.choices = null; // RerunChoices, once loaded
    this.boxes = new Map(); // name -> checkbox
    this.list = h("div", { class: "estimator-list" });
    this.hint = h("p", { class: "hint", id: "rerun-estimators-hint", "data-testid": "rerun-estimators-hint", text: "Loading the estimators…" });
    this.error = errorBox("rerun-estimators-error");
    this.error.id = "rerun-estimators-error";
    this.el = h("fieldset", { class: "choices estimator-picker", "data-testid": "rerun-estimators",
      "aria-describedby": "rerun-estimators-hint rerun-estimators-error" },
    h("legend", { text: "Estimators to re-run" }), this.list, this.hint, this.error);
    this.el.addEventListener("change", () => this.onChange());
  }

  /** Shows the trial's choices (`RerunChoices`). */
  set(choices) {
    this.choices = choices;
    const recorded = new Set(choices.recorded || []);
    const checked = new Set(choices.default);
    const refused = choices.refused || {};
    const names = [...NAMES.filter((n) => choices.runnable.includes(n) || n in refused),
      ...choices.runnable.filter((n) => !NAMES.includes(n))];
    this.boxes.clear();
    this.list.replaceChildren(...names.map((n) => {
      const why = refused[n];
      const box = h("input", { type: "checkbox", name: "rerun-estimator", value: n, id: `rerun-estimator-${n}`,
        "data-testid": `rerun-estimator-${n}`, checked: checked.has(n), disabled: why !== undefined });
      if (why === undefined) this.boxes.set(n, box);
      const note = why !== undefined ? `cannot run: ${why}` : recorded.has(n) ? "recorded" : "";
      return h("label", { class: `choice estimator${why !== undefined ? " refused" : ""}`, for: box.id },
        box, h("span", { class: "estimator-text" },
          h("span", { class: "estimator-name" }, swatch(n, !hasPhase(n)), h("span", { text: estimatorLabel(n) })),
          note ? h("span", { class: "hint", text: note }) : null));
    }));
    this.hint.textContent = !this.boxes.size
      ? "No estimator can run on this trial: it holds no usable sensor frames."
      : choices.recorded
        ? "The stack the trial was recorded with is checked by default. Each one's outputs are overlaid in its own colour."
        : "The trial does not record its stack: every estimator its channels allow is checked by default.";
    this.onChange();
  }

  /** The chosen estimators, in the order a stack runs them (null: not loaded, the server's default). */
  selected() {
    return this.choices ? [...this.boxes].filter(([, b]) => b.checked).map(([n]) => n) : null;
  }

  /** What `RerunRequest.estimators` carries: null when the choice is the default (the recorded stack). */
  request() {
    const s = this.selected();
    if (s === null) return null;
    const d = this.choices.default;
    return s.length === d.length && d.every((n) => s.includes(n)) ? null : s;
  }

  /** Why the choice cannot run (a sentence), or null; shown under the picker. */
  problem() {
    const why = this._why();
    showError(this.error, why);
    return why;
  }

  _why() {
    const s = this.selected();
    if (s === null) return null;
    if (!s.length) return "Choose at least one estimator to re-run.";
    if (!s.some(hasPhase)) {
      const phased = listText(NAMES.filter(hasPhase).map(estimatorLabel), "or");
      return `Choose at least one estimator with a phase (${phased}): the re-run's torque follows one.`;
    }
    for (const n of s) {
      for (const [channel, by] of Object.entries((this.choices.derived || {})[n] || {})) {
        if (!by.some((b) => s.includes(b))) {
          return `${estimatorLabel(n)} needs ${channel}, which this trial does not record: choose ${listText(by.map(estimatorLabel), "or")} too.`;
        }
      }
    }
    return null;
  }

  /** The choice in words, for the submit button: "Timing-based estimate", "3 estimators", "the recorded stack". */
  summary() {
    const s = this.selected();
    if (s === null) return "the recorded stack";
    return s.length <= 2 ? listText(s.map(estimatorLabel)) : `${s.length} estimators`;
  }

  /** The picker could not be loaded: the re-run runs the recorded stack (no `estimators` sent). */
  failed(text) {
    this.hint.textContent = `${text} A re-run runs the recorded stack.`;
    this.onChange();
  }
}
