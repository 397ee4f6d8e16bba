// The review's markers, drawn by the plots' groups (plots.js `PlotGroup.setMarkers`): recorded setting changes
// in words ("Torque gain 1.00 → 1.30, by dr-k", also the re-run form's list), notes (their spans shaded) and
// the other events.

import { fieldName, valueText } from "./events.js";

/** A setting's plain name (wire.js `SETTING_NAMES`, the one table; events.js `fieldName`). */
export const settingLabel = fieldName;

/** "Torque gain 1.00 → 1.30, by dr-k" for a setting `Event` with a field; its own text otherwise. */
export function changeText(ev) {
  if (!ev.field) return `${ev.text}, by ${ev.actor}`;
  return `${fieldName(ev.field)} ${valueText(ev.field, ev.before)} → ${valueText(ev.field, ev.after)}, by ${ev.actor}`;
}

/**
 * Markers of a trial's events for `PlotGroup.setMarkers` ([{t, label, kind}]): setting changes labelled in words,
 * annotations with their text; the other kinds (recording, system, intent) a line each, their text in the hover tip.
 */
export function eventMarkers(events) {
  return events.map((ev) => ({
    t: ev.t, kind: ev.kind,
    label: ev.kind === "setting" ? changeText(ev) : ev.kind === "annotation" ? `Note: ${ev.text}` : "",
  }));
}

/**
 * Markers of review notes: a labelled line at `t` (a span's start; `spanShading` shades it to `t_end`). Notes taken
 * live are the trial's annotation events, drawn by `eventMarkers` already: not twice.
 */
export function noteMarkers(notes) {
  return notes.filter((n) => n.source !== "live").map((n) => ({ t: n.t, kind: "annotation", label: `Note: ${n.text}` }));
}

/** A uPlot plugin shading the spans of review notes (`getNotes()` -> [{t, t_end}], those without t_end skipped). */
export function spanShading(getNotes) {
  return {
    hooks: {
      drawClear: [(u) => {
        const spans = getNotes().filter((n) => n.t_end != null);
        if (!spans.length) return;
        const { ctx, bbox } = u;
        ctx.save();
        ctx.fillStyle = "rgba(11,92,173,0.12)";
        for (const n of spans) {
          const a = Math.max(u.valToPos(n.t, "x", true), bbox.left);
          const b = Math.min(u.valToPos(n.t_end, "x", true), bbox.left + bbox.width);
          if (b > a) ctx.fillRect(a, bbox.top, b - a, bbox.height);
        }
        ctx.restore();
      }],
    },
  };
}

/**
 * A uPlot plugin that writes the labels a `Plot` drew (its `drawnMarkers`) on `el` as `data-marker-labels`
 * (JSON), and where those written on it sit as `data-marker-boxes`, after each draw: what a test, or a screen
 * reader's description, can read of the canvas.
 * @param {HTMLElement} el the plot's container
 * @param {() => object} plot the `Plot` (created after its plugins)
 */
export function markerLabels(el, plot) {
  return {
    hooks: {
      draw: [(u) => {
        const p = plot();
        if (!p) return;
        const shown = p.drawnMarkers.filter((m) => m.label);
        el.dataset.markerLabels = JSON.stringify(shown.map((m) => m.label));
        // where each label written on the plot sits ([left, right], CSS px), and the plot area's width: a test
        // checks that none is cut at an edge
        el.dataset.markerBoxes = JSON.stringify({ width: u.over.clientWidth, boxes: shown.filter((m) => m.row !== null).map((m) => m.box) });
      }],
    },
  };
}
