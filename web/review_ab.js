// A/B review: two to four re-runs of the trial, each named by the user and run with the recorded settings
// (what ran) or "what if" settings, compared by the server (`POST /api/trials/{id}/compare`): their torque
// and phase side by side, each one's difference from the first, their mean strides overlaid, and a table of
// figures (peak torque, mean phase rate, stride length; errors when the trial's ground truth is known).

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { COLORS, Plot } from "./plots.js";
import { SettingsEditor } from "./settings.js";
import { errorBox, fmt, h, runAction, ValidationError } from "./ui.js";

const RUN_COLORS = [COLORS.blue, COLORS.orange, COLORS.green, COLORS.purple];
const MAX_RUNS = 4; // MAX_COMPARED_RUNS in sessions/schema.py
const LETTERS = "ABCD";

/** The figures table's columns: [figure key, heading, digits]; the error ones only with a ground truth. */
/** @type {Array<[string, string, number]>} key in RunFigures, column head, decimals */
const FIGURES = [
  ["strides", "Strides", 0],
  ["peak_torque_Nm", "Peak torque (N·m)", 2],
  ["mean_phase_rate_1_s", "Mean phase rate (strides/s)", 3],
  ["mean_stride_length_m", "Stride length (m)", 3],
];
/** @type {Array<[string, string, number]>} */
const ERRORS = [
  ["phase_rmse_pct", "Phase error (%)", 2],
  ["phase_rate_rmse_1_s", "Phase-rate error (strides/s)", 3],
  ["stride_length_rmse_m", "Stride-length error (m)", 3],
  ["incline_rmse_deg", "Incline error (deg)", 2],
];

/**
 * The A/B card.
 * @param {number} trialId
 * @param {{baseSettings: () => (object | null), range: () => (number[] | null), zoomed: () => boolean,
 *   group: object, plugins: (div: HTMLElement, plot: () => object) => object[]}} hooks the recorded settings
 *   (what-if runs start from them), the view's range, whether the view is zoomed (then only it is compared),
 *   the `PlotGroup` of the time plots (shared zoom, cursor, the review's markers) and their plugins
 */
export function abCard(trialId, hooks) {
  const runs = [];
  const runsBox = h("div", { class: "ab-runs", "data-testid": "ab-runs" });
  const addBtn = h("button", { type: "button", "data-testid": "ab-add", text: "Add a re-run" });
  const compareBtn = h("button", { type: "button", class: "primary", "data-testid": "ab-compare", text: "Compare" });
  const error = errorBox("ab-error");
  const status = h("p", { class: "hint", role: "status", "data-testid": "ab-status" });
  const results = h("div", { class: "ab-results", "data-testid": "ab-results", hidden: true });
  const el = h("section", { class: "card ab-card", "data-testid": "ab-card" },
    h("h2", { text: "A/B: compare re-runs" }),
    h("p", { class: "hint", text: "Each re-run starts from the settings that ran (the recorded ones, with their changes "
      + "where they happened) unless you give it other settings. The first is the reference the others are compared "
      + "with. When the view is zoomed, only the view is compared." }),
    runsBox, h("div", { class: "buttons" }, addBtn, compareBtn), error, status, results);

  function addRun(name, whatIf) {
    const k = runs.length;
    const id = `ab-run-${k}`;
    const nameInput = h("input", { type: "text", id: `${id}-name`, "data-testid": `${id}-name`, value: name, maxlength: 40 });
    const mode = h("select", { id: `${id}-mode`, "data-testid": `${id}-mode`, "aria-label": `Settings of re-run ${LETTERS[k]}` },
      h("option", { value: "recorded", text: "the recorded settings (what ran)" }),
      h("option", { value: "whatif", text: "other settings (what if)" }));
    mode.value = whatIf ? "whatif" : "recorded";
    const editor = new SettingsEditor(id);
    const base = hooks.baseSettings();
    if (base) editor.setBaseline(base);
    const editorBox = h("div", { class: "ab-editor", hidden: !whatIf }, editor.el);
    mode.addEventListener("change", () => {
      editorBox.hidden = mode.value !== "whatif";
    });
    const remove = h("button", { type: "button", class: "small", "data-testid": `${id}-remove`, text: "Remove" });
    const row = h("fieldset", { class: "ab-run", "data-testid": "ab-run" },
      h("legend", {}, h("span", { class: "swatch", style: `background:${RUN_COLORS[k]}` }), ` Re-run ${LETTERS[k]}`),
      h("div", { class: "inline" }, h("label", { for: `${id}-name`, class: "caption", text: "Name" }), nameInput,
        h("label", { for: `${id}-mode`, class: "caption", text: "with" }), mode, remove),
      editorBox);
    const run = { row, nameInput, mode, editor };
    remove.addEventListener("click", () => {
      if (runs.length <= 2) return;
      runs.splice(runs.indexOf(run), 1);
      row.remove();
      sync();
    });
    runs.push(run);
    runsBox.append(row);
    sync();
  }
  function sync() {
    addBtn.disabled = runs.length >= MAX_RUNS;
    for (const r of runs) r.row.querySelector("button.small").disabled = runs.length <= 2;
  }
  addBtn.addEventListener("click", () => addRun(`${LETTERS[runs.length]}`, true));
  addRun("A: as recorded", false);
  addRun("B", true);

  /** The request's runs, validated (names given and unique, settings in bounds). */
  function request() {
    const seen = new Set();
    return runs.map((r, k) => {
      const name = r.nameInput.value.trim();
      if (!name) throw new ValidationError(`Give re-run ${LETTERS[k]} a name.`);
      if (seen.has(name.toLowerCase())) throw new ValidationError(`Two re-runs are named "${name}": give each its own name.`);
      seen.add(name.toLowerCase());
      if (r.mode.value !== "whatif") return { name };
      return { name, settings: { ...(hooks.baseSettings() || {}), ...r.editor.values() } };
    });
  }

  // --- results -------------------------------------------------------------------------------------
  let plots = [];
  function clearPlots() {
    for (const p of plots) p.destroy();
    plots = [];
  }

  function render(c) {
    clearPlots();
    const series = (label) => c.runs.map((r, k) => ({ label: `${r.name}${label}`, color: RUN_COLORS[k] }));
    const torqueDiv = h("div", { class: "plot", "data-testid": "ab-plot-torque" });
    const diffDiv = h("div", { class: "plot", "data-testid": "ab-plot-diff" });
    const strideDiv = h("div", { class: "plot", "data-testid": "ab-plot-stride" });
    const phaseDiv = h("div", { class: "plot", "data-testid": "ab-plot-phase" });
    const ref = c.runs[0].name;
    const table = figuresTable(c);
    results.replaceChildren(
      h("div", { class: "ab-plots" }, torqueDiv, phaseDiv, diffDiv, strideDiv),
      h("h3", { text: "Figures per re-run" }),
      c.ground_truth ? h("p", { class: "hint", "data-testid": "ab-truth", text: `Errors (root mean square) against the ground truth: ${c.ground_truth}.` })
        : h("p", { class: "hint", "data-testid": "ab-truth", text: "No ground truth is known for this trial, so no errors are shown." }),
      h("p", { class: "hint", "data-testid": "ab-start", text: `${ref} (the reference): ${c.runs[0].start || ""}` }),
      h("div", { class: "table-scroll" }, table));
    results.hidden = false;
    const timePlot = (div, spec) => {
      let plot = null;
      plot = new Plot(div, { ...spec, group: hooks.group, plugins: hooks.plugins(div, () => plot) });
      return plot;
    };
    const torque = timePlot(torqueDiv, { title: "Torque command of each re-run", yLabel: "N·m", key: "torque",
      series: series("") });
    torque.setData([c.t, ...c.runs.map((r) => r.torque_Nm)]);
    const phase = timePlot(phaseDiv, { title: "Phase of each re-run", yLabel: "% of cycle", key: "phase", series: series("") });
    phase.setData([c.t, ...c.runs.map((r) => r.phase_pct)]);
    const others = c.runs.slice(1);
    const diff = timePlot(diffDiv, { title: `Difference from ${ref}: torque`, yLabel: "N·m",
      series: others.map((r, k) => ({ label: `${r.name} − ${ref}`, color: RUN_COLORS[k + 1] })) });
    diff.setData([c.t, ...others.map((r) => r.torque_diff_Nm)]);
    // the mean stride of each re-run, its spread across strides as a band (mean ± SD) in its colour
    const n = c.runs.length;
    const stride = new Plot(strideDiv, { title: "Mean stride: torque, mean ± SD", yLabel: "N·m", xLabel: "% of stride",
      series: [
        ...c.runs.map((r, k) => ({ label: r.name, color: RUN_COLORS[k] })),
        ...c.runs.map((r) => ({ label: `${r.name} − SD`, color: "transparent", width: 0 })),
        ...c.runs.map((r) => ({ label: `${r.name} + SD`, color: "transparent", width: 0 })),
      ],
      bands: c.runs.map((r, k) => ({ series: [1 + 2 * n + k, 1 + n + k], fill: `${RUN_COLORS[k]}26` })) });
    const band = (r, sign) => r.stride_torque_mean_Nm.map((m, i) => (m == null || r.stride_torque_sd_Nm[i] == null ? null
      : m + sign * r.stride_torque_sd_Nm[i]));
    stride.setData([c.stride_pct, ...c.runs.map((r) => r.stride_torque_mean_Nm), ...c.runs.map((r) => band(r, -1)),
      ...c.runs.map((r) => band(r, 1))]);
    // the band's edges are drawn as the band, not listed: the legend names each re-run once
    strideDiv.querySelectorAll(".u-legend .u-series").forEach((row, i) => {
      if (i > n) row.hidden = true;
    });
    plots = [torque, phase, diff, stride];
  }

  function figuresTable(c) {
    const cols = [...FIGURES, ...(c.ground_truth ? ERRORS : [])];
    return h("table", { class: "table ab-figures", "data-testid": "ab-figures" },
      h("thead", {}, h("tr", {}, h("th", { text: "Re-run" }), ...cols.map(([, head]) => h("th", { class: "num", text: head })))),
      h("tbody", {}, ...c.runs.map((r, k) => h("tr", { "data-testid": "ab-figures-row" },
        h("th", { scope: "row" }, h("span", { class: "swatch", style: `background:${RUN_COLORS[k]}` }), ` ${r.name}`),
        ...cols.map(([key, , digits]) => h("td", { class: "num", "data-key": key, text: fmt(r.figures[key], digits) }))))));
  }

  compareBtn.addEventListener("click", () => runAction(compareBtn, error, async () => {
    const body = { runs: request() };
    const range = hooks.zoomed() ? hooks.range() : null;
    status.textContent = `Re-running ${body.runs.length} times and comparing…`;
    try {
      const c = await api.compare(trialId, body, { t0: range && range[0], t1: range && range[1],
        max_points: 2000 });
      render(c);
      const changed = body.runs.filter((r) => r.settings).map((r) => r.name);
      status.textContent = `Compared ${c.runs.length} re-runs${range ? ` from ${fmt(range[0], 2)} to ${fmt(range[1], 2)} s` : ""}`
        + `${changed.length ? `; other settings: ${changed.join(", ")}` : ""}.`;
    } catch (err) {
      status.textContent = "";
      throw err;
    }
  }));
  fence(el, "run"); // a comparison re-runs the trial, as a re-run does

  return {
    el,
    /** The recorded settings arrived: the what-if editors start from them. */
    setBaseline(settings) {
      for (const r of runs) r.editor.setBaseline(settings);
    },
    redraw() {
      for (const p of plots) p.redraw();
    },
    destroy: clearPlots,
  };
}
