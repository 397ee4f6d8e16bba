// Linked plots: a shared x zoom, linked cursors, labelled event markers and pause/resume for a group of
// `Plot`s (plots.js). A `Plot` joins a group with `spec.group`; a plot without one is a group of its own.

let _groups = 0;

/** Marker colours per kind (setting changes, annotations, ...); a marker's own `color` wins. */
export const MARKER_COLORS = { setting: "#c2410c", annotation: "#0b5cad", recording: "#1d7a3a", system: "#4b5563",
  intent: "#a21caf", heel_strike: "#6b7280", cursor: "#111111" };

/**
 * A group of plots sharing the x zoom, the cursor, the event markers and pause.
 * @param {{pauseOnZoom?: boolean, onChange?: (g: PlotGroup) => void}} [opts] `pauseOnZoom`: a zoom or pan
 *   pauses the group (a live view: zooming into moving data would let it slide away); `onChange` is called
 *   after every zoom, pan, reset, pause, resume.
 */
export class PlotGroup {
  constructor({ pauseOnZoom = false, onChange = null } = {}) {
    _groups += 1;
    this.key = `gaitscope-plots-${_groups}`;
    this.plots = new Set();
    this.x = null; // [min, max] while zoomed, else null (each plot's own range: following the data)
    this.markers = [];
    this.paused = false;
    this.pauseOnZoom = pauseOnZoom;
    this.context = {};
    this.panMode = false; // a plain drag pans (else it zooms; Shift and drag pans)
    this._listeners = onChange ? [onChange] : [];
  }

  /** Calls `fn(group)` after every zoom, pan, reset, pause and resume. */
  onChange(fn) {
    this._listeners.push(fn);
  }

  _changed() {
    for (const p of this.plots) p._syncTools();
    for (const fn of this._listeners) fn(this);
  }

  add(plot) {
    this.plots.add(plot);
  }

  delete(plot) {
    this.plots.delete(plot);
  }

  /** Pan mode on or off: in pan mode a drag moves along time instead of zooming. */
  setPanMode(on) {
    this.panMode = !!on;
    this._changed();
  }

  /** Zooms every plot of the group to [x0, x1] (in either order; a span under 1e-6 is refused, false). */
  setX(x0, x1) {
    const lo = Math.min(x0, x1);
    const hi = Math.max(x0, x1);
    if (!(Number.isFinite(lo) && Number.isFinite(hi) && hi - lo > 1e-6)) return false;
    if (this.pauseOnZoom && !this.paused) this.pause();
    this.x = [lo, hi];
    for (const p of this.plots) p._applyX();
    this._changed();
    return true;
  }

  /** Back to each plot's own x range (following the data in a live view). */
  resetX() {
    this.x = null;
    for (const p of this.plots) p._applyX();
    this._changed();
  }

  /** The x range shown (the zoom, else the first plot's), or null before any plot has data. */
  view() {
    if (this.x) return this.x;
    for (const p of this.plots) {
      const { min, max } = p.u.scales.x;
      if (min != null && max != null) return [min, max];
    }
    return null;
  }

  /** Zooms by `factor` (< 1 in, > 1 out) about `t` (default: the middle of the view). */
  zoomBy(factor, t) {
    const v = this.view();
    if (!v) return false;
    const c = t ?? (v[0] + v[1]) / 2;
    return this.setX(c - (c - v[0]) * factor, c + (v[1] - c) * factor);
  }

  /** Pans by `fraction` of the view's width (positive: later). */
  panBy(fraction) {
    const v = this.view();
    if (!v) return false;
    const d = (v[1] - v[0]) * fraction;
    return this.setX(v[0] + d, v[1] + d);
  }

  /**
   * The event markers every plot of the group draws: a vertical line at `t` with its `label` written at the
   * top (labels that would overlap go on a second or third row, or are left to the hover text).
   * @param {{t: number, label: string, kind?: string, color?: string}[]} markers
   */
  setMarkers(markers) {
    this.markers = checkMarkers(markers);
    for (const p of this.plots) p.redraw();
  }

  /** Context of the y ranges (for example `{max_torque_Nm}` for the torque's); plots re-ranged. */
  setContext(ctx) {
    this.context = { ...this.context, ...ctx };
    for (const p of this.plots) p._applyY();
  }

  /** Freezes what every plot draws; their `setData` keeps the newest data for `resume`. */
  pause() {
    if (this.paused) return;
    this.paused = true;
    for (const p of this.plots) p._freeze();
    this._changed();
  }

  /** Draws the newest data again, the zoom reset (a live view follows the data again). */
  resume() {
    if (!this.paused) return;
    this.paused = false;
    this.x = null;
    for (const p of this.plots) p._thaw();
    this._changed();
  }
}

/** Markers validated (each needs a finite `t` and a text `label`; a TypeError names the first that lacks one), copied. */
export function checkMarkers(markers) {
  if (!Array.isArray(markers)) throw new TypeError("setMarkers: expected a list of {t, label, kind}");
  markers.forEach((m, i) => {
    if (!m || !Number.isFinite(m.t)) throw new TypeError(`setMarkers: marker ${i} has no finite time t`);
    if (typeof m.label !== "string") throw new TypeError(`setMarkers: marker ${i} has no text label`);
  });
  return markers.map((m) => ({ ...m }));
}

const _LABEL_FONT = "12px system-ui, sans-serif";
const _ROWS = 3;

/**
 * Where a marker's label goes (canvas pixels): right of its line at `x`, or left of it near the right edge, and
 * always inside the plot area (`bbox`): moved in from an edge, and cut with "…" when wider than the plot. The
 * label's `text` as drawn, its box's `left` and width `w` (issue #23: labels cut at the plot's edge).
 */
export function markerLabelBox(ctx, label, x, bbox, pr) {
  const pad = 8 * pr;
  let text = label;
  let w = ctx.measureText(text).width + pad;
  if (w > bbox.width) {
    let n = text.length;
    while (n > 1 && ctx.measureText(`${text.slice(0, n)}…`).width + pad > bbox.width) n--;
    text = `${text.slice(0, n)}…`;
    w = Math.min(ctx.measureText(text).width + pad, bbox.width);
  }
  const right = bbox.left + bbox.width;
  const left = x + w > right ? x - w : x;
  return { text, w, left: Math.min(Math.max(left, bbox.left), right - w) };
}

/**
 * Draws labelled markers on a uPlot (`getMarkers()` -> [{t, label, kind, color}]) and records what it drew
 * in `drawn` ([{t, label, kind, x (CSS px in the plot area), row (null: label left to the hover text), text (as
 * drawn: cut with "…" when wider than the plot), box ([left, right] of its label, CSS px in the plot area)}]);
 * `pr`: uPlot's pixel ratio (canvas pixels per CSS pixel).
 */
export function drawMarkers(u, markers, drawn, pr) {
  drawn.length = 0;
  if (!markers.length) return;
  const { ctx, bbox } = u;
  const rowH = 16 * pr;
  const rowEnd = new Array(_ROWS).fill(-Infinity);
  const sorted = [...markers].sort((a, b) => a.t - b.t);
  ctx.save();
  ctx.beginPath();
  ctx.rect(bbox.left, bbox.top, bbox.width, bbox.height);
  ctx.clip();
  ctx.font = _LABEL_FONT.replace("12px", `${12 * pr}px`);
  ctx.textBaseline = "middle";
  ctx.textAlign = "left";
  for (const m of sorted) {
    const x = Math.round(u.valToPos(m.t, "x", true));
    if (x < bbox.left || x > bbox.left + bbox.width) continue;
    const color = m.color || MARKER_COLORS[m.kind] || MARKER_COLORS.system;
    ctx.strokeStyle = color;
    ctx.lineWidth = 2 * pr;
    ctx.setLineDash([4 * pr, 3 * pr]);
    ctx.beginPath();
    ctx.moveTo(x, bbox.top);
    ctx.lineTo(x, bbox.top + bbox.height);
    ctx.stroke();
    ctx.setLineDash([]);
    const { text, left, w } = markerLabelBox(ctx, m.label, x, bbox, pr);
    let row = null;
    for (let r = 0; r < _ROWS; r++) {
      if (left > rowEnd[r] + 4 * pr) {
        row = r;
        break;
      }
    }
    if (row !== null && m.label) {
      rowEnd[row] = left + w;
      const y = bbox.top + 2 * pr + row * rowH;
      ctx.fillStyle = "rgba(255,255,255,0.92)";
      ctx.fillRect(left, y, w, rowH - 2 * pr);
      ctx.strokeStyle = color;
      ctx.lineWidth = 1 * pr;
      ctx.strokeRect(left, y, w, rowH - 2 * pr);
      ctx.fillStyle = "#111";
      ctx.fillText(text, left + 4 * pr, y + (rowH - 2 * pr) / 2);
    }
    drawn.push({ t: m.t, label: m.label, kind: m.kind || null, x: (x - bbox.left) / pr, row, text,
      box: [(left - bbox.left) / pr, (left + w - bbox.left) / pr] });
  }
  ctx.restore();
}
