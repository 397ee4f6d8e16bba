// The live view's per-stride overlays (live.js): the torque and the foot angle over the gait cycle, mean ± SD
// of the last 20 strides, the newest stride, and the subject's baseline: the mean stride kept in this browser
// (per subject code) to compare against.

import { bandPlot } from "./live_plots.js";
import { COLORS, StrideOverlay } from "./plots.js";
import { h } from "./ui.js";

export class StrideCard {
  constructor() {
    this.overlay = new StrideOverlay(["torque_Nm", "foot_angle_deg", "phase_rate", "stride_length_m", "incline_deg"]);
    this.dirty = false; // a stride (or the baseline) changed since the last draw
    this.subjectCode = "";
    /** @type {Array<{c: string, plot: any}> | null} the band plots, once the card is in the page */
    this.bands = null;
    this.strideCount = h("span", { class: "hint", "data-testid": "stride-count", text: "waiting for heel strikes…" });
    this.bandTorque = h("div", { class: "plot", "data-testid": "overlay-torque" });
    this.bandFoot = h("div", { class: "plot", "data-testid": "overlay-foot" });
    this.baselineNote = h("span", { class: "hint", "data-testid": "baseline-note", text: "" });
    const setBaselineBtn = h("button", { type: "button", "data-testid": "set-baseline", text: "Set as baseline" });
    this.clearBaselineBtn = h("button", { type: "button", "data-testid": "clear-baseline", text: "Clear baseline" });
    setBaselineBtn.addEventListener("click", () => {
      const means = this.overlay.snapshot();
      if (!means) {
        this.baselineNote.textContent = "no complete stride yet";
        return;
      }
      const saved = { means, strides: this.overlay.count, when: new Date().toLocaleString() };
      localStorage.setItem(this._key(), JSON.stringify(saved));
      this._showBaseline(saved);
    });
    this.clearBaselineBtn.addEventListener("click", () => {
      localStorage.removeItem(this._key());
      this._showBaseline(null);
    });
    this.el = h("section", { class: "card overlay" },
      h("div", { class: "card-head" }, h("h2", { text: "Per stride: mean ± SD of the last 20" }), this.strideCount),
      h("div", { class: "overlay-plots" }, this.bandTorque, this.bandFoot),
      h("div", { class: "baseline-row" }, setBaselineBtn, this.clearBaselineBtn, this.baselineNote));
  }

  _key() {
    return `gaitscope.baseline.${this.subjectCode}`;
  }

  _showBaseline(saved) {
    this.overlay.setBaseline(saved ? saved.means : null);
    this.baselineNote.textContent = saved ? `baseline: ${saved.strides} stride${saved.strides === 1 ? "" : "s"} of ${saved.when}` : "no baseline";
    this.clearBaselineBtn.disabled = !saved;
    this.dirty = true;
  }

  /** The band plots, drawn once the card is in the page. */
  start() {
    this.bands = [
      { c: "torque_Nm", plot: bandPlot(this.bandTorque, "Torque command", "N·m", COLORS.orange, { line: "#e8a07f", band: "rgba(194,65,12,0.18)" }) },
      { c: "foot_angle_deg", plot: bandPlot(this.bandFoot, "Foot angle (measured)", "deg", COLORS.blue, { line: "#7fa6d1", band: "rgba(11,92,173,0.18)" }) },
    ];
  }

  /** The session's subject (a hello): its baseline stored in this browser, if any. */
  setSubject(code) {
    this.subjectCode = code;
    try {
      this._showBaseline(JSON.parse(localStorage.getItem(this._key()) || "null"));
    } catch {
      this._showBaseline(null); // an unreadable stored baseline is dropped, not fatal
    }
  }

  /** A sample's row: true when it completed a stride. */
  push(t, row, heelStrike) {
    if (this.overlay.push(t, row, heelStrike)) this.dirty = true;
  }

  /** The bands drawn again when a stride (or the baseline) changed. */
  draw() {
    if (!this.dirty || !this.bands) return;
    this.dirty = false;
    for (const b of this.bands) b.plot.setData(this.overlay.bandData(b.c));
    this.strideCount.textContent = `${this.overlay.count} stride${this.overlay.count === 1 ? "" : "s"}`;
  }

  destroy() {
    if (this.bands) for (const b of this.bands) b.plot.destroy();
  }
}
