// The toolbar of a `Plot` (plot_view.js): zoom in and out, move earlier and later, pan mode, reset, the
// y range form (remembered per signal), large-plot mode, and what the plot shows (paused, zoomed).

import { parseRange, storedRange, storeRange, Y_RANGES } from "./plot_ranges.js";
import { fmt, h } from "./ui.js";

/**
 * The toolbar of `plot`: its element, and `sync()` to show the group's state (called on every change).
 * @returns {{el: HTMLElement, sync: () => void}}
 */
export function plotTools(plot) {
  const btn = (action, text, label) => h("button", { type: "button", class: "plot-btn", "data-action": action,
    "data-testid": `plot-${action}`, "aria-label": label, title: label, text });
  const zoomIn = btn("zoom-in", "+", "Zoom in (or turn the mouse wheel over the plot)");
  const zoomOut = btn("zoom-out", "−", "Zoom out");
  const earlier = btn("earlier", "‹", "Earlier: move the view back by a quarter of its width");
  const later = btn("later", "›", "Later: move the view forward by a quarter of its width");
  const pan = btn("pan", "Pan", "Pan: drag to move along time (or hold Shift and drag)");
  const reset = btn("reset", "Reset", "Show the whole range again (or double-click the plot)");
  const large = btn("enlarge", "⤢", "Large plot: fill the window (Esc returns)");
  const signal = Y_RANGES[plot.yKey] ? Y_RANGES[plot.yKey].name : "this plot";
  const yBtn = btn("y-range", "Y range", `Set the vertical range of ${signal} (remembered in this browser)`);
  const state = h("span", { class: "plot-state", "data-testid": "plot-state", role: "status" });
  const lo = h("input", { type: "number", step: "any", inputmode: "decimal", "data-testid": "plot-y-min", "aria-label": "Lowest value shown" });
  const hi = h("input", { type: "number", step: "any", inputmode: "decimal", "data-testid": "plot-y-max", "aria-label": "Highest value shown" });
  const unit = h("span", { class: "plot-y-unit" });
  const apply = h("button", { type: "submit", class: "plot-btn", "data-testid": "plot-y-apply", text: "Apply" });
  const resetY = h("button", { type: "button", class: "plot-btn", "data-testid": "plot-y-default", text: "Default" });
  const err = h("p", { class: "plot-y-error", role: "alert", "data-testid": "plot-y-error" });
  const form = h("form", { class: "plot-yform", "data-testid": "plot-y-form", hidden: true },
    h("label", {}, "From ", lo), h("label", {}, " to ", hi), unit, apply, resetY, err);
  const el = h("div", { class: "plot-tools", "data-testid": "plot-tools" },
    state, ...(plot.zoomable ? [zoomIn, zoomOut, earlier, later, pan, reset] : []), ...(plot.yKey ? [yBtn] : []), large, form);
  large.addEventListener("click", () => plot.setLarge(!plot.large));
  zoomIn.addEventListener("click", () => plot.zoomAt(0.5));
  zoomOut.addEventListener("click", () => plot.zoomAt(2));
  earlier.addEventListener("click", () => plot.group.panBy(-0.25));
  later.addEventListener("click", () => plot.group.panBy(0.25));
  pan.addEventListener("click", () => plot.group.setPanMode(!plot.group.panMode));
  reset.addEventListener("click", () => plot.group.resetX());
  yBtn.addEventListener("click", () => {
    form.hidden = !form.hidden;
    yBtn.setAttribute("aria-expanded", String(!form.hidden));
    if (form.hidden) return;
    const { min, max } = plot.u.scales.y;
    lo.value = min == null ? "" : String(+min.toPrecision(4));
    hi.value = max == null ? "" : String(+max.toPrecision(4));
    unit.textContent = plot._unit({});
    err.textContent = "";
    lo.focus();
  });
  form.addEventListener("submit", (e) => {
    e.preventDefault();
    try {
      storeRange(plot.yKey, parseRange(lo.value, hi.value));
    } catch (x) {
      err.textContent = x.message;
      return;
    }
    form.hidden = true;
    yBtn.setAttribute("aria-expanded", "false");
    plot._rangeChanged();
  });
  resetY.addEventListener("click", () => {
    storeRange(plot.yKey, null);
    form.hidden = true;
    yBtn.setAttribute("aria-expanded", "false");
    plot._rangeChanged();
  });
  return { el, sync: () => sync(plot, { pan, reset, yBtn, state, large }) };
}

/** The toolbar's buttons and state text as the plot's group stands. */
function sync(plot, t) {
  const g = plot.group;
  t.pan.setAttribute("aria-pressed", String(!!g.panMode));
  t.large.setAttribute("aria-pressed", String(plot.large));
  t.large.textContent = plot.large ? "✕" : "⤢";
  t.large.title = plot.large ? "Back to the page (Esc)" : "Large plot: fill the window (Esc returns)";
  t.reset.disabled = !g.x;
  plot.container.classList.toggle("gs-paused", g.paused);
  plot.container.classList.toggle("gs-pan-mode", !!g.panMode);
  const user = plot.yKey ? storedRange(plot.yKey) : null;
  t.yBtn.classList.toggle("on", !!user);
  t.yBtn.textContent = user ? `Y ${fmt(user[0], 1)} to ${fmt(user[1], 1)}` : "Y range";
  t.state.textContent = g.paused ? (g.x ? "paused, zoomed" : "paused") : g.x ? "zoomed" : "";
}
