// The live view's summary figures (live.js): phase (or the stance phase of a stance-phase primary), cadence,
// stride length, speed, incline, the last stride's peak torque, and seed 001's speed-change intent when the
// session runs it (what the walker is about to do).

import { STANCE_PHASE, estimatorLabel } from "./estimators.js";
import { fmt, h } from "./ui.js";

/** What a figure is shown for when no estimator estimates it (issue #23: never a number nobody estimated). */
export const NOT_ESTIMATED = "not estimated";
/** The gait-state quantity each tile shows (the speed needs the stride length and the rate). */
const TILE_QUANTITIES = { cad: ["phase_rate"], sl: ["stride_length_m"], sp: ["stride_length_m", "phase_rate"], inc: ["incline_deg"] };

export class LiveSummary {
  constructor() {
    const cell = (key, label, unit) => {
      const v = h("span", { class: "value", "data-testid": `summary-${key}`, text: "–" });
      return [h("div", { class: "metric" }, h("span", { class: "label", text: label }), v, h("span", { class: "unit", text: unit })), v];
    };
    const [phaseCell, phaseV] = cell("phase", "Phase", "%");
    const [cadCell, cadV] = cell("cadence", "Cadence", "strides/min");
    const [slCell, slV] = cell("stride-length", "Stride length", "m");
    const [spCell, spV] = cell("speed", "Speed", "m/s");
    const [incCell, incV] = cell("incline", "Incline", "deg");
    const [pkCell, pkV] = cell("peak-torque", "Peak torque, last stride", "N·m");
    // shown from the start (issue #23: in the first screen, its place kept); "–" until the stack's intent estimator says
    const [intentCell, intentV] = cell("intent", "Speed-change intent", "");
    this.v = { phase: phaseV, cad: cadV, sl: slV, sp: spV, inc: incV, pk: pkV, intent: intentV };
    this.phaseLabel = phaseCell.querySelector(".label");
    this.intentCell = intentCell;
    this.intentUnit = intentCell.querySelector(".unit");
    // where the figures come from when not from the primary, and what the torque assumes in their place
    this.sourceNote = h("p", { class: "summary-sources muted", "data-testid": "summary-sources", hidden: true });
    this.sources = null; // GaitState.sources: quantity -> estimator (absent: not estimated); null: not yet known
    this.el = h("div", { class: "summary", "data-testid": "summary" }, phaseCell, cadCell, slCell, spCell, incCell, pkCell, intentCell, this.sourceNote);
  }

  /**
   * Where each figure comes from (a `GaitState`'s `sources`, sent on the first state and when they change) and
   * the values the torque profile assumes for what the primary does not estimate (`torque_assumes`).
   * @param {Record<string, string>} sources @param {Record<string, number> | null | undefined} assumes
   */
  setSources(sources, assumes) {
    this.sources = sources;
    const primary = sources.phase || null;
    const lines = [];
    const from = new Map();
    for (const q of ["phase_rate", "stride_length_m", "incline_deg"]) {
      const name = sources[q];
      if (name && name !== primary) from.set(name, [...(from.get(name) || []), QUANTITY_WORDS[q]]);
    }
    for (const [name, words] of from) lines.push(`${capitalize(words.join(" and "))} from ${estimatorLabel(name)}.`);
    const missing = ["stride_length_m", "incline_deg"].filter((q) => !sources[q]).map((q) => QUANTITY_WORDS[q]);
    if (missing.length) lines.push(`${capitalize(missing.join(" and "))}: not estimated by any estimator of this session.`);
    const a = assumes || {};
    const assumed = [];
    if (a.stride_length_m != null) assumed.push(`a ${fmt(a.stride_length_m, 2)} m stride`);
    if (a.incline_deg != null) assumed.push(a.incline_deg === 0 ? "level ground" : `a ${fmt(a.incline_deg, 1)} deg incline`);
    if (assumed.length && primary) lines.push(`The torque assumes ${assumed.join(" and ")} (${estimatorLabel(primary)} does not estimate them).`);
    this.sourceNote.textContent = lines.join(" ");
    this.sourceNote.hidden = lines.length === 0;
    for (const [key, qs] of Object.entries(TILE_QUANTITIES)) {
      const cell = this.v[key].parentElement;
      const absent = qs.some((q) => !sources[q]);
      cell.dataset.source = absent ? "none" : qs.map((q) => sources[q]).join(",");
      cell.title = absent ? NOT_ESTIMATED : qs.map((q) => `${QUANTITY_WORDS[q]}: ${estimatorLabel(sources[q])}`).join("; ");
    }
  }

  /** A tile's text: "not estimated" when a quantity it shows has no source, else the number. */
  figure(key, value, digits) {
    const s = this.sources;
    if (s && TILE_QUANTITIES[key].some((q) => !s[q])) return NOT_ESTIMATED;
    return fmt(value, digits);
  }

  /** A primary with a stance phase puts it in the gait state: the summary says which phase it shows. */
  setPrimary(primary) {
    this.phaseLabel.textContent = STANCE_PHASE.has(primary) ? `Stance phase (${primary})` : "Phase";
  }

  /** The intent estimator's last class (1 speeding up, -1 slowing down, 0 steady), desired speed and confidence. */
  showIntent(e) {
    if (!e || !e.columns || !e.columns.intent_code) return;
    const { intentCell, intentUnit } = this;
    intentCell.hidden = false;
    const codes = e.columns.intent_code;
    const last = codes.length - 1;
    if (e.failed || last < 0 || codes[last] == null) {
      this.v.intent.textContent = e.failed ? "failed" : "–";
      intentUnit.textContent = "";
      intentCell.dataset.intent = "unknown";
      return;
    }
    const code = codes[last];
    const word = code > 0.5 ? "speeding up" : code < -0.5 ? "slowing down" : "steady";
    this.v.intent.textContent = word;
    intentCell.dataset.intent = word.replace(" ", "-");
    const desired = e.columns.desired_speed_m_s ? e.columns.desired_speed_m_s[last] : null;
    const conf = e.columns.intent_confidence ? e.columns.intent_confidence[last] : null;
    intentUnit.textContent = `desired ${fmt(desired, 2)} m/s · ${fmt(conf, 1)} SD`;
  }

  /**
   * The figures from the last complete stride, else the newest sample.
   * @param {(col: string) => any} last the newest value of a plot column
   * @param {import("./plots.js").StrideOverlay} overlay the stride overlay
   * @param {string | null} primary the estimator driving the torque
   */
  update(last, overlay, primary) {
    const v = this.v;
    v.phase.textContent = fmt(last("phase_pct"), 1);
    const st = overlay.lastStride; // the last complete stride, else the newest sample
    // a stance-phase primary's rate is the stance's, not the stride's: the cadence is then the stride's duration
    const rate = STANCE_PHASE.has(primary) ? (st ? 1 / st.duration : NaN) : st ? st.mean.phase_rate : last("phase_rate");
    const sl = st ? st.mean.stride_length_m : last("stride_length_m");
    v.cad.textContent = this.figure("cad", 60 * rate, 1);
    v.sl.textContent = this.figure("sl", sl, 2);
    v.sp.textContent = this.figure("sp", sl * rate, 2);
    v.inc.textContent = this.figure("inc", st ? st.mean.incline_deg : last("incline_deg"), 1);
    v.pk.textContent = fmt(st ? st.peak.torque_Nm : NaN, 1);
  }
}

const QUANTITY_WORDS = { phase_rate: "cadence", stride_length_m: "stride length", incline_deg: "incline" };
const capitalize = (text) => text.charAt(0).toUpperCase() + text.slice(1);
