// uPlot wrappers, the live ring buffer, the per-stride overlay and min/max decimation.
// Memory is bounded everywhere: the ring and the stride store are fixed-size typed arrays.

import uPlot from "./vendor/uPlot.esm.js";

export { uPlot };

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

const _AXIS = { stroke: "#111", font: "14px system-ui, sans-serif", labelFont: "bold 14px system-ui, sans-serif",
  grid: { stroke: "#d0d4da", width: 1 }, ticks: { stroke: "#9aa0a6", width: 1 } };

/** Colours with strong contrast on white, distinguishable with common colour-vision deficiencies. */
export const COLORS = { blue: "#0b5cad", orange: "#c2410c", green: "#1d7a3a", purple: "#6b21a8", teal: "#0f766e", grey: "#4b5563" };

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

/** uPlot options of one y series of a spec: a line, or (`points`) dots without a line. */
function _seriesOpts(s) {
  return {
    label: s.label, stroke: s.color, width: s.width || 2, dash: s.dash, spanGaps: !!s.spanGaps,
    ...(s.points ? { paths: () => null, points: { show: true, size: 10, width: 2, fill: s.color } } : { points: { show: false } }),
    value: s.value || ((u, v) => (v == null ? "–" : v.toFixed(2))),
  };
}

/**
 * A line plot of columns against time (or any x) that follows its container's width.
 * @param {HTMLElement} container
 * @param {{title: string, yLabel: string, xLabel?: string, series: {label: string, color: string,
 *   dash?: number[], width?: number, spanGaps?: boolean, points?: boolean, value?: Function}[],
 *   height?: number, xRange?: Function, yRange?: number[]|Function, bands?: object[], plugins?: object[],
 *   drag?: boolean, onSelect?: (x0: number, x1: number) => void}} spec
 */
export class Plot {
  constructor(container, spec) {
    this.container = container;
    this.spec = spec;
    this.height = spec.height || 170;
    this._build(spec.series);
    this._observer = new ResizeObserver(() => {
      const w = Math.max(container.clientWidth, 300);
      if (w !== this.u.width) this.u.setSize({ width: w, height: this.height });
    });
    this._observer.observe(container);
  }

  _build(series) {
    const spec = this.spec;
    const onSelect = spec.onSelect;
    const opts = {
      title: spec.title,
      width: Math.max(this.container.clientWidth, 300),
      height: this.height,
      scales: { x: { time: false, ...(spec.xRange ? { range: spec.xRange } : {}) },
        y: spec.yRange ? { range: spec.yRange } : {} },
      axes: [{ ..._AXIS, label: spec.xLabel || "time (s)" }, { ..._AXIS, label: spec.yLabel, size: 60 }],
      series: [
        { label: spec.xLabel || "t (s)", value: (u, v) => (v == null ? "–" : v.toFixed(2)) },
        ...series.map(_seriesOpts),
      ],
      bands: spec.bands,
      legend: { live: true },
      cursor: { drag: { x: !!spec.drag, y: false, setScale: false }, points: { show: false } },
      plugins: spec.plugins || [],
      hooks: onSelect ? { setSelect: [(u) => {
        if (u.select.width < 4) return;
        const x0 = u.posToVal(u.select.left, "x");
        const x1 = u.posToVal(u.select.left + u.select.width, "x");
        u.setSelect({ left: 0, width: 0, top: 0, height: 0 }, false);
        onSelect(x0, x1);
      }] } : {},
    };
    this.series = series;
    const empty = [new Float64Array(0), ...series.map(() => new Float64Array(0))];
    this.u = new uPlot(opts, empty, this.container);
  }

  /**
   * Replaces the plotted series (legend included) when they differ from the current ones; the data
   * follows with the next `setData`. (The plot is rebuilt: uPlot's `delSeries` fails without cursor points.)
   * @returns {boolean} whether they changed
   */
  setSeries(series) {
    const key = (list) => JSON.stringify(list.map((s) => [s.label, s.color, s.dash, s.width, !!s.points]));
    if (key(series) === key(this.series)) return false;
    this.u.destroy();
    this._build(series);
    return true;
  }

  /** Replaces the data: `[x, ...series]` arrays of equal length. */
  setData(data) {
    this.u.setData(data);
  }

  redraw() {
    this.u.redraw(false, false);
  }

  destroy() {
    this._observer.disconnect();
    this.u.destroy();
  }
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
