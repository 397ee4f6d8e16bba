// uPlot wrappers, the live ring buffer, the per-stride overlay and min/max decimation.
// Memory is bounded everywhere: the ring and the stride store are fixed-size typed arrays.
//
// ===================================== Plot API (issue #12) ==========================================
// Import everything from this module. Existing calls keep working unchanged: `new Plot(div, spec)`,
// `setSeries`, `setData`, `redraw`, `destroy`, `markersPlugin`, `spec.onSelect` + `spec.drag`.
//
// new Plot(container, spec): spec options (new ones marked *)
//   title, yLabel, xLabel, series [{label, color, dash, width, spanGaps, points, value, unit*}], height,
//   xRange ([a, b] or (u, min, max) => [a, b], e.g. a live window following the data), yRange, bands,
//   plugins, drag + onSelect (a drag reports [x0, x1] to onSelect INSTEAD of zooming: the review timeline)
//   * group: a PlotGroup. Plots of one group share the x zoom, the cursor (hover values at the same time in
//     every plot), the event markers and pause. Without one, the plot is a group of its own.
//   * key / yKey: the signal, a key of Y_RANGES (plot_ranges.js: phase, stance, phase_rate, incline,
//     stride_length, stride, torque, foot, shank, joints, thigh, hip, knee, ankle, intent, speed). Gives the
//     default y range and the unit; with a key the plot has a "Y range" control (min/max, "Default"),
//     remembered in localStorage ("gaitscope.plots.y.<key>") and applied to every plot of that key on the
//     page. Per-stride band plots: pass yKey ("torque", "foot") to give them the table's range too.
//     y range used: the user's > spec.yRange > the data fitted, at least the table's `fit` span (incline, phase
//     rate, stride length, speed; issue #23) > Y_RANGES[key] > auto. Leave yRange out to use the table.
//   * unit: unit of the hover values (default: the series' `unit`, the table's, else from yLabel,
//     "% of cycle" -> "%"). Shown after each legend value (CSS ::after, data-unit); the legend's
//     .u-value textContent stays the bare number (tests read it).
//   * zoom: false to turn zoom and pan off (default on).   * tools: false to hide the toolbar.
// Interaction (every zoomable plot): drag across = zoom that time range (all plots of the group);
//   mouse wheel = zoom about the cursor (zooming out past the data resets; within 0.4 s of a page scroll
//   the wheel scrolls the page instead); Shift+drag, or a drag in pan mode (toolbar "Pan"), = pan;
//   double-click or "Reset" = back to the plot's own range (a live window follows the data again); toolbar
//   "+"/"−" zoom about the middle, "‹"/"›" move a quarter of the view (touch screens, keyboard).
// Drawing: a plot out of view (scrolled away, in a hidden panel) only keeps the data setData gives it and
//   draws the newest when it shows again, so calling setData on every plot at every frame stays cheap.
// Plot methods (new): setMarkers(list) (this plot's own markers, drawn with its group's), zoomAt(factor, t),
//   pause(), resume(), paused, yRange(), drawnMarkers ([{t, label, kind, x, row}] of the last draw; row
//   null: no room for the label, its text is in the hover tip), group, u (the uPlot).
//
// new PlotGroup({pauseOnZoom = false, onChange = null})
//   setX(x0, x1) zoom every plot (false if refused), resetX(), view() -> [x0, x1] shown, x (zoom or null),
//   zoomBy(factor, t?) (< 1 in), panBy(fraction of the view, + later): for keyboard shortcuts (+/-, arrows).
//   setMarkers([{t, label, kind, color?}]): a labelled vertical line per marker in every plot; kinds with a
//     colour (MARKER_COLORS): setting, annotation, recording, system, intent, heel_strike, cursor; hovering
//     within 6 px of a line shows "label (at t s)" in a tip. Throws TypeError naming a marker without t/label.
//   setContext({max_torque_Nm}) context of the table's ranges (the torque's is 0 to the session's bound).
//   pause(): every plot keeps drawing what it showed (a copy) while its setData keeps only the newest data;
//     zoom and pan work on the paused view. resume(): draws the newest data, zoom reset (catches up).
//     paused; pauseOnZoom: a zoom or pan pauses first (for a live view). setPanMode(on), panMode.
//   onChange(fn): fn(group) after every zoom, pan, reset, pause, resume (e.g. to label a Pause button).
//
// measureFrames(seconds = 5) -> Promise<{fps, p95_ms, p50_ms, mean_ms, max_ms, frames, seconds, over_20ms}>
//   requestAnimationFrame intervals (plot_frametime.js). From a test:
//   page.evaluate("async () => (await import('/plot_frametime.js')).measureFrames(5)")
// =====================================================================================================

import { COLORS, Plot } from "./plot_view.js";
import uPlot from "./vendor/uPlot.esm.js";

export { measureFrames } from "./plot_frametime.js";
export { MARKER_COLORS, PlotGroup } from "./plot_group.js";
export { fitRange, storedRange, storeRange, unitOf, Y_RANGES } from "./plot_ranges.js";
export { COLORS, Plot, uPlot };

/**
 * Fixed-capacity columns of float64 samples. Each sample is written twice (at i and i + capacity) so the
 * newest `length` samples are always one contiguous subarray: no copying to hand them to uPlot.
 * Missing values (null) are stored as NaN and returned as null, which uPlot draws as gaps.
 */
export class Ring {
  constructor(capacity, columns) {
    this.capacity = capacity;
    this.columns = columns;
    this.buf = Object.fromEntries(columns.map((c) => [c, new Float64Array(2 * capacity)]));
    this.nan = Object.fromEntries(columns.map((c) => [c, 0])); // NaNs among the stored samples
    this.n = 0;
  }

  get length() {
    return Math.min(this.n, this.capacity);
  }

  clear() {
    this.n = 0;
    for (const c of this.columns) this.nan[c] = 0;
  }

  /** Appends one sample; `row[column]` null/undefined/non-finite -> missing. */
  push(row) {
    const cap = this.capacity;
    const w = this.n % cap;
    const full = this.n >= cap;
    for (const c of this.columns) {
      const b = this.buf[c];
      if (full && Number.isNaN(b[w])) this.nan[c] -= 1;
      let v = row[c];
      if (v === null || v === undefined || !Number.isFinite(v)) {
        v = NaN;
        this.nan[c] += 1;
      }
      b[w] = v;
      b[w + cap] = v;
    }
    this.n += 1;
  }

  /** The newest value of a column (NaN if empty). */
  last(column) {
    if (this.n === 0) return NaN;
    return this.buf[column][((this.n - 1) % this.capacity) + this.capacity];
  }

  /** The newest `count` samples of a column, oldest first (a subarray, or an array with nulls). */
  tail(column, count) {
    const cap = this.capacity;
    const end = (this.n % cap) + cap;
    const sub = this.buf[column].subarray(end - count, end);
    if (this.nan[column] === 0) return sub;
    return Array.from(sub, (v) => (Number.isNaN(v) ? null : v));
  }

  /**
   * uPlot data `[t, ...columns]` for the samples whose `timeColumn` is within `seconds` of the newest.
   * `timeColumn` must increase; the first sample kept is found by bisection.
   */
  window(timeColumn, columns, seconds) {
    const len = this.length;
    if (len === 0) return [new Float64Array(0), ...columns.map(() => new Float64Array(0))];
    const t = this.tail(timeColumn, len);
    const t0 = t[len - 1] - seconds;
    let lo = 0;
    let hi = len - 1;
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (t[mid] < t0) lo = mid + 1;
      else hi = mid;
    }
    const count = len - lo;
    return [t.subarray(lo), ...columns.map((c) => this.tail(c, count))];
  }
}

/** Draws vertical lines at `getMarkers()` -> [{t, color}] (events on a timeline, a review cursor). */
export function markersPlugin(getMarkers) {
  return {
    hooks: {
      draw: [(u) => {
        const marks = getMarkers();
        if (!marks || !marks.length) return;
        const { ctx, bbox } = u;
        ctx.save();
        for (const m of marks) {
          const x = Math.round(u.valToPos(m.t, "x", true));
          if (x < bbox.left || x > bbox.left + bbox.width) continue;
          ctx.strokeStyle = m.color || COLORS.grey;
          ctx.lineWidth = (m.width || 2) * uPlot.pxRatio;
          ctx.setLineDash(m.dash || []);
          ctx.beginPath();
          ctx.moveTo(x, bbox.top);
          ctx.lineTo(x, bbox.top + bbox.height);
          ctx.stroke();
        }
        ctx.restore();
      }],
    },
  };
}

/** Linear interpolation of `y(x)` at `n` equally spaced points of [x[0], x[last]] (NaN where y is). */
function _resample(x, y, count, out) {
  const n = out.length;
  const x0 = x[0];
  const span = x[count - 1] - x0;
  let j = 0;
  for (let k = 0; k < n; k++) {
    const xi = x0 + (span * k) / (n - 1);
    while (j < count - 2 && x[j + 1] < xi) j++;
    const dx = x[j + 1] - x[j];
    const a = dx > 0 ? (xi - x[j]) / dx : 0;
    out[k] = y[j] + Math.min(Math.max(a, 0), 1) * (y[j + 1] - y[j]);
  }
}

/**
 * Strides cut at heel strikes, each normalised to 0-100 % of its cycle (`points` samples), the last `n`
 * kept; mean and SD per point of every channel. Strides outside 0.3-4 s (standing, missed strikes) are
 * left out.
 */
export class StrideOverlay {
  constructor(channels, { n = 20, points = 101, maxSamples = 2048, minS = 0.3, maxS = 4.0 } = {}) {
    this.channels = channels;
    this.n = n;
    this.points = points;
    this.minS = minS;
    this.maxS = maxS;
    this.maxSamples = maxSamples;
    this.cur = { t: new Float64Array(maxSamples), count: 0, open: false };
    for (const c of channels) this.cur[c] = new Float64Array(maxSamples);
    this.store = Object.fromEntries(channels.map((c) => [c, new Float64Array(n * points)]));
    this.stored = 0; // strides ever stored
    this.pct = Float64Array.from({ length: points }, (_, k) => (100 * k) / (points - 1));
    this.mean = Object.fromEntries(channels.map((c) => [c, new Float64Array(points)]));
    this.sd = Object.fromEntries(channels.map((c) => [c, new Float64Array(points)]));
    this.lastStride = null; // {t0, t1, duration, mean: {c}, peak: {c}}
    this.baseline = null; // {c: Float64Array(points)}: a reference mean to compare with, or null
  }

  /** The current mean of every channel as a plain object (to keep as a baseline), or null if empty. */
  snapshot() {
    if (!this.count) return null;
    return Object.fromEntries(this.channels.map((c) => [c, Array.from(this.mean[c])]));
  }

  /** Show `means` (from `snapshot()`) as the baseline curve; null removes it. */
  setBaseline(means) {
    this.baseline = means ? Object.fromEntries(Object.entries(means).map(([c, a]) => [c, Float64Array.from(a)])) : null;
  }

  _append(t, row) {
    const cur = this.cur;
    if (cur.count >= this.maxSamples) {
      cur.open = false; // too long to be a stride: wait for the next heel strike
      cur.count = 0;
      return;
    }
    cur.t[cur.count] = t;
    for (const c of this.channels) {
      const v = row[c];
      cur[c][cur.count] = v === null || v === undefined ? NaN : v;
    }
    cur.count += 1;
  }

  /** Adds a sample; returns true when it closed a stride (so the overlay changed). */
  push(t, row, heelStrike) {
    let closed = false;
    if (heelStrike) {
      if (this.cur.open) {
        this._append(t, row); // the strike ends this stride at 100 % ...
        closed = this._close();
      }
      this.cur.count = 0;
      this.cur.open = true; // ... and starts the next at 0 %
    }
    if (this.cur.open) this._append(t, row);
    return closed;
  }

  _close() {
    const cur = this.cur;
    const count = cur.count;
    if (count < 5) return false;
    const duration = cur.t[count - 1] - cur.t[0];
    if (!(duration >= this.minS && duration <= this.maxS)) return false;
    const slot = (this.stored % this.n) * this.points;
    const summary = { t0: cur.t[0], t1: cur.t[count - 1], duration, mean: {}, peak: {} };
    for (const c of this.channels) {
      const y = cur[c];
      _resample(cur.t, y, count, this.store[c].subarray(slot, slot + this.points));
      let s = 0;
      let k = 0;
      let peak = -Infinity;
      for (let i = 0; i < count; i++) {
        if (Number.isNaN(y[i])) continue;
        s += y[i];
        k += 1;
        if (y[i] > peak) peak = y[i];
      }
      summary.mean[c] = k ? s / k : NaN;
      summary.peak[c] = k ? peak : NaN;
    }
    this.stored += 1;
    this.lastStride = summary;
    this._stats();
    return true;
  }

  _stats() {
    const m = Math.min(this.stored, this.n);
    for (const c of this.channels) {
      const st = this.store[c];
      for (let k = 0; k < this.points; k++) {
        let s = 0;
        let s2 = 0;
        let q = 0;
        for (let j = 0; j < m; j++) {
          const v = st[j * this.points + k];
          if (Number.isNaN(v)) continue;
          s += v;
          s2 += v * v;
          q += 1;
        }
        const mean = q ? s / q : NaN;
        this.mean[c][k] = mean;
        this.sd[c][k] = q > 1 ? Math.sqrt(Math.max(s2 / q - mean * mean, 0) * (q / (q - 1))) : 0;
      }
    }
  }

  /** Strides in the current mean (at most `n`). */
  get count() {
    return Math.min(this.stored, this.n);
  }

  /** uPlot data for one channel: [pct, mean, mean - sd, mean + sd, newest stride, baseline]. */
  bandData(c) {
    const p = this.points;
    const lo = new Float64Array(p);
    const hi = new Float64Array(p);
    for (let k = 0; k < p; k++) {
      lo[k] = this.mean[c][k] - this.sd[c][k];
      hi[k] = this.mean[c][k] + this.sd[c][k];
    }
    const slot = ((this.stored - 1) % this.n) * p;
    const newest = this.stored ? this.store[c].slice(slot, slot + p) : new Float64Array(p).fill(NaN);
    const nulls = (a) => Array.from(a, (v) => (Number.isNaN(v) ? null : v));
    const base = this.baseline && this.baseline[c] ? this.baseline[c] : new Float64Array(p).fill(NaN);
    return [this.pct, nulls(this.mean[c]), nulls(lo), nulls(hi), nulls(newest), nulls(base)];
  }
}

/**
 * Min/max-preserving decimation of columns sharing `t` (increasing) to at most about `maxPoints`:
 * per bucket, the samples holding each column's minimum and maximum. Returns {t, [col]: array}.
 */
export function decimateMinMax(t, cols, maxPoints) {
  const names = Object.keys(cols);
  const n = t.length;
  const perBucket = 2 * Math.max(names.length, 1);
  const buckets = Math.max(1, Math.floor(maxPoints / perBucket));
  if (n <= maxPoints) return { t: Array.from(t), ...Object.fromEntries(names.map((c) => [c, Array.from(cols[c])])) };
  const size = Math.ceil(n / buckets);
  const keep = [];
  for (let b0 = 0; b0 < n; b0 += size) {
    const b1 = Math.min(n, b0 + size);
    const idx = new Set([b0]);
    for (const c of names) {
      const y = cols[c];
      let iMin = -1;
      let iMax = -1;
      for (let i = b0; i < b1; i++) {
        const v = y[i];
        if (v === null || v === undefined || Number.isNaN(v)) continue;
        if (iMin < 0 || v < y[iMin]) iMin = i;
        if (iMax < 0 || v > y[iMax]) iMax = i;
      }
      if (iMin >= 0) idx.add(iMin);
      if (iMax >= 0) idx.add(iMax);
    }
    keep.push(...[...idx].sort((a, b) => a - b));
  }
  return { t: keep.map((i) => t[i]), ...Object.fromEntries(names.map((c) => [c, keep.map((i) => cols[c][i])])) };
}
