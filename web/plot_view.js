// The `Plot` class (re-exported by plots.js, whose header documents its options): a uPlot line plot that
// follows its container's width, with zoom and pan, a cursor linked to its group's, hover values with
// units, labelled event markers, a y range from the table of plot_ranges.js (adjustable, remembered) and
// pause/resume. Its toolbar is plot_tools.js.

import uPlot from "./vendor/uPlot.esm.js";
import { checkMarkers, drawMarkers, PlotGroup } from "./plot_group.js";
import { defaultRange, fitRange, storedRange, unitOf, Y_RANGES } from "./plot_ranges.js";
import { plotTools } from "./plot_tools.js";
import { fmt, h } from "./ui.js";

const _AXIS = { stroke: "#111", font: "13px system-ui, sans-serif", labelFont: "bold 13px system-ui, sans-serif",
  grid: { stroke: "#d0d4da", width: 1 }, ticks: { stroke: "#9aa0a6", width: 1, size: 4 }, gap: 3 };
// Issue #23: the data take most of a plot's card. The title, the y unit and the toolbar share one row above the
// canvas (`.plot-head`); the axes carry numbers, not labels (the unit is in the head; a time axis needs none);
// the legend is one line of fixed height (plots.css), so hover values never move the layout.
const _X_AXIS_PX = 26;
const _Y_AXIS_PX = 40;

/** Colours with strong contrast on white, distinguishable with common colour-vision deficiencies. */
export const COLORS = { blue: "#0b5cad", orange: "#c2410c", green: "#1d7a3a", purple: "#6b21a8", teal: "#0f766e", grey: "#4b5563" };

const _WHEEL_IN = 0.8; // x span per wheel step towards the user (zoom in); its inverse away
const _NEAR_PX = 6; // a marker's hover text shows within this many CSS pixels of its line

/** uPlot options of one y series of a spec: a line, or (`points`) dots without a line. */
function _seriesOpts(s) {
  return {
    label: s.label, stroke: s.color, width: s.width || 2, dash: s.dash, spanGaps: !!s.spanGaps,
    ...(s.points ? { paths: () => null, points: { show: true, size: 10, width: 2, fill: s.color } } : { points: { show: false } }),
    value: s.value || ((u, v) => (v == null ? "–" : v.toFixed(2))),
  };
}

/** The plots alive on the page (a y range set on one applies to every plot of the same signal). */
const _live = new Set();

// The mouse wheel zooms a plot unless the page is being scrolled: a wheel turned within this long of a scroll
// keeps scrolling the page when a plot passes under the mouse.
const _SCROLL_GRACE_MS = 400;
let _lastScroll = -Infinity;
addEventListener("scroll", () => (_lastScroll = performance.now()), { passive: true, capture: true });

/** The plot shown large (at most one), and the key that returns it. */
let _largeOne = null;
function _escLarge(e) {
  if (e.key === "Escape" && _largeOne) {
    e.preventDefault();
    _largeOne.setLarge(false);
  }
}

/** A container's horizontal padding (px): the canvas fits inside it. */
function _padOf(el) {
  const cs = getComputedStyle(el);
  return (parseFloat(cs.paddingLeft) || 0) + (parseFloat(cs.paddingRight) || 0);
}

const _copy = (a) => (a && typeof a.slice === "function" ? a.slice() : a);

/**
 * A line plot of columns against time (or any x) that follows its container's width. The spec's options are
 * listed at the top of plots.js.
 * @param {HTMLElement} container
 * @param {{title: string, yLabel: string, xLabel?: string, series: {label: string, color: string,
 *   dash?: number[], width?: number, spanGaps?: boolean, points?: boolean, value?: Function, unit?: string}[],
 *   height?: number, xRange?: number[]|Function, yRange?: number[]|Function, bands?: object[], plugins?: object[],
 *   drag?: boolean, onSelect?: (x0: number, x1: number) => void, group?: PlotGroup, key?: string,
 *   yKey?: string, unit?: string, zoom?: boolean, tools?: boolean}} spec
 */
export class Plot {
  constructor(container, spec) {
    this.container = container;
    this.spec = spec;
    this.height = spec.height || 170;
    this.group = spec.group || new PlotGroup();
    this.zoomable = spec.zoom !== false;
    this.yKey = spec.yKey || spec.key || null;
    this.markers = [];
    this.drawnMarkers = []; // what the last draw showed: [{t, label, kind, x, row}] (row null: hover text only)
    this._frozen = false;
    this._pending = null; // newest data not drawn yet: paused, or off screen
    this._visible = true; // (part of) the plot on screen: off screen, setData only keeps the data
    this._hover = false;
    container.classList.add("gs-plot");
    this.tools = spec.tools === false ? null : plotTools(this);
    this.unitEl = h("span", { class: "plot-unit", "data-testid": "plot-unit", title: spec.yLabel || "" });
    this.head = h("div", { class: "plot-head" }, this.unitEl, ...(this.tools ? [this.tools.el] : []));
    container.append(this.head);
    this.large = false; // enlarged to fill the window (`setLarge`)
    this.tip = h("div", { class: "plot-marker-tip", role: "tooltip", "data-testid": "plot-marker-tip", hidden: true });
    this._build(spec.series);
    this.group.add(this);
    _live.add(this);
    if (this.group.paused) this._freeze();
    this._syncTools();
    this.unitEl.textContent = this._unit({}); // "%" for "% of cycle": the head keeps its room for the title
    this._observer = new ResizeObserver(() => this._fit());
    this._observer.observe(container);
    // A plot scrolled out of view (or in a closed panel) does not redraw at every frame of a live view: its
    // newest data is drawn when it shows again.
    this._seen = new IntersectionObserver((entries) => {
      this._visible = entries[entries.length - 1].isIntersecting;
      if (this._visible && !this._frozen && this._pending) {
        const d = this._pending;
        this._pending = null;
        this.u.setData(d);
      }
    });
    this._seen.observe(container);
  }

  // --- ranges ----------------------------------------------------------------------------------------
  /** The x range without the group's zoom: the spec's (a function, or fixed), else the data's. */
  _ownX(u, min, max) {
    const sx = this.spec.xRange;
    if (typeof sx === "function") return sx(u, min, max);
    if (Array.isArray(sx)) return sx;
    if (min == null || max == null) return [0, 1];
    return min === max ? [min - 0.5, max + 0.5] : [min, max];
  }

  /** The y range now: the user's (remembered), else the spec's or the table's, else null (auto). */
  yRange() {
    const user = this.yKey ? storedRange(this.yKey) : null;
    return user || defaultRange(this.yKey, this.spec.yRange, this.group.context);
  }

  _yScale(u, min, max) {
    const user = this.yKey ? storedRange(this.yKey) : null;
    const fitted = user || this.spec.yRange ? null : fitRange(this.yKey, min, max);
    if (fitted) return fitted;
    const r = this.yRange();
    if (typeof r === "function") return r(u, min, max);
    if (r) return r;
    if (min == null || max == null) return [0, 1];
    return uPlot.rangeNum(min, max, 0.1, true);
  }

  /** The unit of a series' hover value: its own, the spec's, the table's, else from the y label. */
  _unit(s) {
    return s.unit ?? this.spec.unit ?? (Y_RANGES[this.yKey] ? Y_RANGES[this.yKey].unit : unitOf(this.spec.yLabel));
  }

  _build(series) {
    const spec = this.spec;
    const zoom = this.zoomable;
    const opts = {
      title: spec.title,
      width: Math.max(this.container.clientWidth - _padOf(this.container), 300),
      height: this.height,
      scales: { x: { time: false, range: (u, min, max) => this.group.x || this._ownX(u, min, max) },
        y: { range: (u, min, max) => this._yScale(u, min, max) } },
      axes: [{ ..._AXIS, size: _X_AXIS_PX, ...(spec.xLabel ? { label: spec.xLabel, labelSize: 18, labelGap: 0 } : {}) },
        { ..._AXIS, size: _Y_AXIS_PX }],
      series: [
        { label: spec.xLabel || "t (s)", value: (u, v) => (v == null ? "–" : v.toFixed(2)) },
        ...series.map(_seriesOpts),
      ],
      bands: spec.bands,
      padding: /** @type {[number, number, number, number]} */ ([8, 12, 0, 0]), // the axes' labels need no more room than their numbers
      legend: { live: true },
      cursor: {
        drag: { x: zoom || !!spec.drag, y: false, setScale: false },
        points: { show: false },
        // the cursor moves in every plot of the group; drags, clicks and double-clicks stay in their own
        sync: { key: this.group.key, setSeries: false, filters: { pub: (type) => type === "mousemove" || type === "mouseleave" } },
        bind: {
          mousedown: (u, targ, fn, onlyTarg) => (e) => {
            if (e.button !== 0 || (onlyTarg && e.target !== targ)) return null;
            if (zoom && (e.shiftKey || this.group.panMode)) this._pan(e);
            else fn(e);
            return null;
          },
          dblclick: (u, targ, fn, onlyTarg) => (e) => {
            if (e.button !== 0 || (onlyTarg && e.target !== targ)) return null;
            if (zoom) this.group.resetX();
            else fn(e);
            return null;
          },
        },
      },
      plugins: spec.plugins || [],
      hooks: {
        setSelect: [(u) => {
          if (u.select.width < 4) return;
          const x0 = u.posToVal(u.select.left, "x");
          const x1 = u.posToVal(u.select.left + u.select.width, "x");
          u.setSelect({ left: 0, width: 0, top: 0, height: 0 }, false);
          if (spec.onSelect) spec.onSelect(x0, x1);
          else if (zoom) this.group.setX(x0, x1);
        }],
        draw: [(u) => drawMarkers(u, [...this.group.markers, ...this.markers], this.drawnMarkers, uPlot.pxRatio)],
        setCursor: [(u) => this._showTip(u)],
        // no unit after a missing value ("–")
        setLegend: [() => {
          for (const v of this._values) v.classList.toggle("gs-none", v.textContent === "–");
        }],
      },
    };
    this.series = series;
    this._values = [];
    const empty = [new Float64Array(0), ...series.map(() => new Float64Array(0))];
    this.u = new uPlot(opts, empty, this.container);
    this._rebuilt = true;
    // the title joins the unit and the toolbar in the head (same element and class: `.u-title`)
    const title = this.u.root.querySelector(".u-title");
    if (this._title) this._title.remove();
    this._title = title;
    if (title) {
      title.setAttribute("title", spec.title);
      this.head.prepend(title);
    }
    // hover values with their unit: written after the number by CSS (plots.css), the number stays the text
    this._values = [];
    this.u.root.querySelectorAll(".u-legend .u-series").forEach((row, i) => {
      const unit = i === 0 ? "" : this._unit(series[i - 1]);
      const v = /** @type {HTMLElement | null} */ (row.querySelector(".u-value"));
      if (!unit || !v) return;
      v.dataset.unit = unit;
      v.classList.toggle("gs-none", v.textContent === "–");
      this._values.push(v);
    });
    this.u.over.append(this.tip);
    this.u.over.addEventListener("mouseenter", () => (this._hover = true));
    this.u.over.addEventListener("mouseleave", () => {
      this._hover = false;
      this.tip.hidden = true;
    });
    if (zoom) {
      this.u.over.addEventListener("wheel", (e) => {
        if (performance.now() - _lastScroll < _SCROLL_GRACE_MS) return;
        e.preventDefault();
        const rect = this.u.over.getBoundingClientRect();
        this.zoomAt(e.deltaY < 0 ? _WHEEL_IN : 1 / _WHEEL_IN, this.u.posToVal(e.clientX - rect.left, "x"));
      }, { passive: false });
    }
  }

  // --- size ------------------------------------------------------------------------------------------
  /** Follows the container's width (and, enlarged, the window's height). */
  _fit() {
    const w = Math.max(this.container.clientWidth - _padOf(this.container), 300);
    const hgt = this.large ? Math.max(200, innerHeight - 120) : this.height; // the head, legend and frame take the rest
    if (w !== this.u.width || hgt !== this.u.height) this.u.setSize({ width: w, height: hgt });
  }

  /**
   * Large-plot mode: the plot fills the window above the page (Esc, or the toolbar's button, returns).
   * @param {boolean} on
   */
  setLarge(on) {
    if (on === this.large) return;
    this.large = on;
    this.container.classList.toggle("gs-large", on);
    if (on) {
      _largeOne?.setLarge(false);
      _largeOne = this;
      document.addEventListener("keydown", _escLarge);
    } else if (_largeOne === this) {
      _largeOne = null;
      document.removeEventListener("keydown", _escLarge);
    }
    this._fit();
    if (this.tools) this.tools.sync();
  }

  // --- zoom and pan ----------------------------------------------------------------------------------
  /** Zooms the group by `factor` about `t`; zooming out past this plot's own range resets the zoom. */
  zoomAt(factor, t) {
    const v = this.group.view();
    if (!v) return;
    const c = t ?? (v[0] + v[1]) / 2;
    const lo = c - (c - v[0]) * factor;
    const hi = c + (v[1] - c) * factor;
    const own = this._ownBase();
    if (factor > 1 && own && lo <= own[0] && hi >= own[1]) this.group.resetX();
    else this.group.setX(lo, hi);
  }

  /** This plot's x range without the zoom, from its data; null without data. */
  _ownBase() {
    const t = this.u.data[0];
    if (!t || !t.length) return null;
    return this._ownX(this.u, t[0], t[t.length - 1]);
  }

  _pan(e) {
    const u = this.u;
    const v = this.group.view();
    if (!v) return;
    const x0 = e.clientX;
    const width = u.over.clientWidth || 1;
    this.container.classList.add("gs-panning");
    const move = (ev) => {
      const dt = ((ev.clientX - x0) / width) * (v[1] - v[0]);
      this.group.setX(v[0] - dt, v[1] - dt);
    };
    const up = () => {
      document.removeEventListener("mousemove", move);
      document.removeEventListener("mouseup", up);
      this.container.classList.remove("gs-panning");
    };
    document.addEventListener("mousemove", move);
    document.addEventListener("mouseup", up);
  }

  /** Applies the group's zoom (or, without one, the plot's own range) to the drawn data. */
  _applyX() {
    const own = this._ownBase();
    const r = this.group.x || own;
    if (r) this.u.setScale("x", { min: r[0], max: r[1] });
    this._syncTools();
  }

  /** Re-ranges y (after the user's range or the context changed). */
  _applyY() {
    const d = this.u.data;
    if (d && d[0] && d[0].length) this.u.setData(d, true);
    else this.u.redraw(true, true);
    this._syncTools();
  }

  // --- markers ---------------------------------------------------------------------------------------
  /** This plot's own markers (drawn with its group's): [{t, label, kind?, color?}]. */
  setMarkers(markers) {
    this.markers = checkMarkers(markers);
    this.redraw();
  }

  _showTip(u) {
    if (!this._hover || u.cursor.left == null || u.cursor.left < 0) {
      this.tip.hidden = true;
      return;
    }
    let best = null;
    for (const m of this.drawnMarkers) {
      const d = Math.abs(m.x - u.cursor.left);
      if (d <= _NEAR_PX && (!best || d < best.d)) best = { m, d };
    }
    if (!best) {
      this.tip.hidden = true;
      return;
    }
    this.tip.textContent = `${best.m.label} (at ${fmt(best.m.t, 2)} s)`;
    this.tip.hidden = false;
    const right = best.m.x > u.over.clientWidth / 2;
    this.tip.style.left = right ? "" : `${best.m.x + 8}px`;
    this.tip.style.right = right ? `${u.over.clientWidth - best.m.x + 8}px` : "";
  }

  // --- pause -----------------------------------------------------------------------------------------
  /** Pauses this plot's group (see `PlotGroup.pause`). */
  pause() {
    this.group.pause();
  }

  /** Resumes this plot's group (see `PlotGroup.resume`). */
  resume() {
    this.group.resume();
  }

  get paused() {
    return this.group.paused;
  }

  /** Keeps what is drawn (a copy: a live ring overwrites the arrays it handed out). */
  _freeze() {
    this._frozen = true;
    const fresh = !!this._pending; // an off-screen plot freezes its newest data, not what it drew last
    const d = this._pending || this.u.data;
    this._pending = null;
    if (d && d[0] && d[0].length) this.u.setData(d.map(_copy), fresh);
    this._rebuilt = false;
    this._syncTools();
  }

  _thaw() {
    this._frozen = false;
    const d = this._pending;
    this._pending = null;
    if (d) this.u.setData(d);
    else this._applyX();
    this._syncTools();
  }

  // --- toolbar (plot_tools.js) -----------------------------------------------------------------------
  /** The user's y range changed: every plot of the page showing the same signal follows. */
  _rangeChanged() {
    for (const p of _live) if (p.yKey === this.yKey) p._applyY();
  }


  _syncTools() {
    if (this.tools) this.tools.sync();
  }

  // --- data ------------------------------------------------------------------------------------------
  /**
   * Replaces the plotted series (legend included) when they differ from the current ones; the data
   * follows with the next `setData`. (The plot is rebuilt: uPlot's `delSeries` fails without cursor points.)
   * @returns {boolean} whether they changed
   */
  setSeries(series) {
    const key = (list) => JSON.stringify(list.map((s) => [s.label, s.color, s.dash, s.width, !!s.points, s.unit]));
    if (key(series) === key(this.series)) return false;
    this.u.destroy();
    this._build(series);
    return true;
  }

  /** Replaces the data: `[x, ...series]` arrays of equal length. While paused, kept for `resume`. */
  setData(data) {
    if ((this._frozen && !this._rebuilt) || (!this._visible && !this._frozen)) {
      this._pending = data;
      return;
    }
    this.u.setData(this._frozen ? data.map(_copy) : data);
    this._rebuilt = false;
  }

  redraw() {
    this.u.redraw(false, false);
  }

  destroy() {
    this.setLarge(false);
    _live.delete(this);
    this.group.delete(this);
    this._observer.disconnect();
    this._seen.disconnect();
    this.u.destroy();
    this.head.remove();
  }
}

