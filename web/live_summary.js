// The live view's summary figures (live.js): phase (or the stance phase of a stance-phase primary), cadence,
// stride length, speed, incline, the last stride's peak torque, and seed 001's speed-change intent when the
// session runs it (what the walker is about to do).

import { STANCE_PHASE } from "./estimators.js";
import { fmt, h } from "./ui.js";

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
    const [intentCell, intentV] = cell("intent", "Speed-change intent", "");
    intentCell.hidden = true;
    this.v = { phase: phaseV, cad: cadV, sl: slV, sp: spV, inc: incV, pk: pkV, intent: intentV };
    this.phaseLabel = phaseCell.querySelector(".label");
    this.intentCell = intentCell;
    this.intentUnit = intentCell.querySelector(".unit");
    this.el = h("div", { class: "summary", "data-testid": "summary" }, phaseCell, cadCell, slCell, spCell, incCell, pkCell, intentCell);
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
    v.cad.textContent = fmt(60 * rate, 1);
    v.sl.textContent = fmt(sl, 2);
    v.sp.textContent = fmt(sl * rate, 2);
    v.inc.textContent = fmt(st ? st.mean.incline_deg : last("incline_deg"), 1);
    v.pk.textContent = fmt(st ? st.peak.torque_Nm : NaN, 1);
  }
}
