// The live view's plots of estimator outputs that their descriptors ask for (wire.js `ESTIMATORS[name].plots`):
// one plot per plot hint of each estimator a batch shows the stack runs, a line per output, following the newest
// 10 s with the view's other plots (shared zoom, cursor and pause). Estimators whose outputs the view draws on a
// card of its own (`except`: the intent estimator's desired vs actual speed) are left to it. An estimator
// registered with a plot hint is drawn here without any edit of the view.

import { COLORS, Plot, Ring } from "./plots.js";
import { h } from "./ui.js";
import { ESTIMATORS, QUANTITY_NAMES } from "./wire.js";

const LINE_COLORS = [COLORS.blue, COLORS.orange, COLORS.green, COLORS.purple, COLORS.teal, COLORS.grey];
const CAPACITY = 2048; // > 10 s at the 60 Hz the stream is asked for, as the view's own ring

export class EstimatorPlots {
  /**
   * @param {HTMLElement} box where the plots go (appended as estimators appear)
   * @param {object} opts the view's plot options: `group`, `xRange`, `seconds` (the window), `except` (names)
   */
  constructor(box, { group, xRange, seconds, except = [] }) {
    this.box = box;
    this.opts = { group, xRange };
    this.seconds = seconds;
    this.except = new Set(except);
    /** @type {Map<string, {name: string, outputs: string[], div: HTMLElement, plot: Plot, ring: Ring, lastT: number}>} */
    this.shown = new Map();
    this.dirty = false;
  }

  /** The plots of the estimators this batch holds (created the first time one comes), then their samples. */
  push(states, estimators) {
    for (const [name, e] of Object.entries(estimators || {})) {
      const info = Object.hasOwn(ESTIMATORS, name) ? ESTIMATORS[name] : null;
      if (!info || this.except.has(name) || !e.columns) continue;
      for (const p of info.plots) {
        const key = `${name}.${p.key}`;
        let entry = this.shown.get(key);
        if (!entry) entry = this._add(key, name, p);
        for (let i = 0; i < states.length; i++) {
          const t = states[i].t;
          if (t <= entry.lastT) {
            if (t === entry.lastT) continue; // already shown (a reconnection's history)
            entry.ring.clear(); // the source restarted
          }
          entry.lastT = t;
          const row = { t };
          for (const o of entry.outputs) row[o] = e.columns[o] ? e.columns[o][i] : null;
          entry.ring.push(row);
        }
        this.dirty = true;
      }
    }
  }

  _add(key, name, p) {
    const div = h("div", { class: "plot", "data-testid": `plot-${p.key}` });
    this.box.append(div);
    // each line by what it is on screen (its quantity's name, else its output's in words) and its estimator's label
    const info = ESTIMATORS[name];
    const what = (o) => (QUANTITY_NAMES[info.quantities[o]] || { name: o.replace(/_(deg|dps|m_s|m|Nm|spm)$/, "").replace(/_/g, " ") }).name;
    const series = p.outputs.map((o, i) => ({ label: `${what(o)} (${info.label})`, color: LINE_COLORS[i % LINE_COLORS.length] }));
    const plot = new Plot(div, { key: p.key, title: p.title, yLabel: p.y_label, cols: p.outputs, series, ...this.opts });
    const entry = { name, outputs: [...p.outputs], div, plot, ring: new Ring(CAPACITY, ["t", ...p.outputs]), lastT: -Infinity };
    this.shown.set(key, entry);
    return entry;
  }

  /** Draws what came since the last draw (at most once per animation frame). */
  draw() {
    if (!this.dirty) return;
    this.dirty = false;
    for (const e of this.shown.values()) e.plot.setData(e.ring.window("t", e.outputs, this.seconds));
  }

  destroy() {
    for (const e of this.shown.values()) e.plot.destroy();
    this.shown.clear();
  }
}
