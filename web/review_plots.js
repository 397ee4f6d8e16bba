// The review's plots of the view (the range zoomed to, or the whole trial): the live view's gait-state plots
// with a re-run's overlaid, the strides in view (mean ± SD), and the speed-change intent (seed 001) as the trial
// recorded it, desired vs actual speed (or the channels the trial lacks for it), with a re-run's overlaid when
// the re-run ran the intent estimator. The knee of the hip and knee plot is drawn only from every sample (a
// view the server did not decimate): see `derive`. review.js loads the view and the re-run; this draws them.

import { estimatorLabel, estimatorOverlay, INTENT, listText, rerunEstimators } from "./estimators.js";
import { bandPlot, INTENT_SPEC, intentValue, kneeFlexion, PLOT_SPECS } from "./live_plots.js";
import { COLORS, decimateMinMax, Plot, StrideOverlay, uPlot } from "./plots.js";
import { RERUN_POINTS } from "./review_rerun.js";
import { h, ValidationError } from "./ui.js";

/** The canvas height of each review plot: with its head and one-line legend, the data take >= 60 % (issue #23). */
const REVIEW_HEIGHT = 260;

export const MAX_POINTS = 2000; // per request, as the server decimates
const RERUN_COLS = { phase: "phase_pct", torque: "torque_Nm", incline: "incline_deg" }; // plot key -> column
const RERUN_STYLE = { label: "re-run", color: COLORS.purple, width: 2 }; // the re-run's gait state
const INTENT_RERUN_COLS = INTENT ? INTENT_SPEC.cols.map((c) => `${INTENT}.${c}`) : []; // a re-run's intent outputs
const INTENT_RERUN_SERIES = INTENT_SPEC.series.map((s) => ({ ...s, label: `${s.label}, re-run`, width: 1.5, dash: [2, 3] }));

/**
 * Series columns plus phase in % (the plots' unit) and the hip and knee flexion; nulls kept. Above
 * `maxPoints` samples the server decimates, each bucket's rows holding every angle's own extremes, which are
 * not at the same instants: thigh − shank is then no knee angle, so the knee is left out (null, and
 * `kneeLeftOut` says so when there was one to show). Fewer rows than `maxPoints` are every sample.
 * @param {Record<string, any>} series a `/series` or re-run answer (columns by name)
 * @param {number} maxPoints the `max_points` it was asked with
 * @returns {Record<string, any>} its columns and the derived ones, and `kneeLeftOut`
 */
export function derive(series, maxPoints) {
  const pct = (a) => (a || []).map((v) => (v == null ? null : v * 100));
  const decimated = (series.t || []).length >= maxPoints;
  const thigh = series.thigh_angle_deg || [];
  const shank = series.shank_angle_deg || [];
  const knee = thigh.map((v, i) => (decimated ? null : kneeFlexion(v, shank[i])));
  const some = (a) => a.some((v) => v != null);
  return { ...series, phase_pct: pct(series.phase), tbe_pct: pct(series.tbe_phase), hip_flex_deg: thigh,
    knee_flex_deg: knee, kneeLeftOut: decimated && some(thigh) && some(shank) };
}

/**
 * A re-run's answer as the plots overlay it (the server puts it on the recording's session times: no alignment
 * here): `rerun` (its times, the columns drawn, each plot's estimator series, whether it ran the intent
 * estimator), the estimators it ran and those drawn. Throws when it holds no samples.
 */
export function rerunOverlay(res) {
  const r = derive(res, RERUN_POINTS);
  if (!r.t || !r.t.length) throw new ValidationError("The re-run produced no samples (the trial has no raw sensor frames).");
  const names = rerunEstimators(res);
  const overlay = estimatorOverlay(names, res);
  const intent = INTENT_RERUN_COLS.length > 0 && INTENT_RERUN_COLS.every((c) => Array.isArray(res[c]));
  const rerun = { t: r.t, cols: { ...Object.fromEntries(Object.values(RERUN_COLS).map((c) => [c, r[c]])), ...overlay.cols,
    ...(intent ? Object.fromEntries(INTENT_RERUN_COLS.map((c) => [c, res[c]])) : {}) }, series: overlay.series, intent };
  return { rerun, names, drawn: overlay.drawn };
}

/**
 * @param {Record<string, any>} st the review's state, read here: `view` and `intentView` (the series and the
 *   IntentSeries in view), `intent` (the whole trial's IntentSeries), `rerun` (`rerunOverlay`'s), `range`
 * @param {{group: import("./plots.js").PlotGroup, plugins: (div: HTMLElement, plot: () => any) => any[]}} hooks
 *   the plots' group (shared zoom, cursor, markers) and a time plot's plugins
 */
export function reviewPlots(st, hooks) {
  const { group } = hooks;
  const plotsBox = h("div", { class: "plots" });
  // under the hip and knee plot, when its knee is left out (`derive`)
  const kneeNote = h("p", { class: "hint", "data-testid": "review-knee-note", hidden: true,
    text: `Knee: zoom to fewer than ${MAX_POINTS} samples to see it; a longer view keeps each angle's extremes, `
      + "which are not at the same instants." });
  const plots = PLOT_SPECS.map((spec) => {
    const div = h("div", { class: "plot", "data-testid": `review-plot-${spec.key}` });
    plotsBox.append(div, ...(spec.key === "joints" ? [kneeNote] : []));
    const entry = { spec };
    entry.plot = new Plot(div, { ...spec, group, series: [...spec.series, ...overlaySeries(spec.key)], height: REVIEW_HEIGHT,
      plugins: hooks.plugins(div, () => entry.plot) });
    return entry;
  });
  // desired vs actual speed: the recorded intent, or why there is none
  const intentNote = h("p", { class: "hint", "data-testid": "review-intent-note", text: "Loading the speed-change intent…" });
  const intentDiv = h("div", { class: "plot", "data-testid": "review-plot-intent", hidden: true });
  const intentCard = h("section", { class: "card", "data-testid": "review-intent" },
    h("h2", { text: "Speed-change intent (seed 001): desired vs actual speed" }), intentNote, intentDiv);
  const intentRef = { plot: null };
  const intentPlot = new Plot(intentDiv, { ...INTENT_SPEC, group, height: REVIEW_HEIGHT,
    plugins: hooks.plugins(intentDiv, () => intentRef.plot) });
  intentRef.plot = intentPlot;
  const strideNote = h("span", { class: "hint", "data-testid": "review-stride-count" });
  const bandT = h("div", { class: "plot" });
  const bandF = h("div", { class: "plot" });
  const overlayCard = h("section", { class: "card overlay" },
    h("div", { class: "card-head" }, h("h2", { text: "Strides in view: mean ± SD" }), strideNote),
    h("div", { class: "overlay-plots" }, bandT, bandF));
  const bands = [
    { c: "torque_Nm", plot: bandPlot(bandT, "Torque command", "N·m", COLORS.orange, { line: "#e8a07f", band: "rgba(194,65,12,0.18)" }) },
    { c: "foot_angle_deg", plot: bandPlot(bandF, "Foot angle (measured)", "deg", COLORS.blue, { line: "#7fa6d1", band: "rgba(11,92,173,0.18)" }) },
  ];

  /** A plot's re-run series after its own: the gait state's column, then the estimators' ({..., col}). */
  function overlaySeries(key) {
    return [...(RERUN_COLS[key] ? [{ ...RERUN_STYLE, col: RERUN_COLS[key] }] : []), ...((st.rerun && st.rerun.series[key]) || [])];
  }

  function rerunSlice(t0, t1, cols) {
    const r = st.rerun;
    if (!r) return null;
    let i0 = r.t.findIndex((t) => t >= t0);
    if (i0 < 0) return null;
    let i1 = i0;
    while (i1 < r.t.length && r.t[i1] <= t1) i1++;
    return decimateMinMax(r.t.slice(i0, i1), Object.fromEntries(cols.map((c) => [c, r.cols[c].slice(i0, i1)])), MAX_POINTS);
  }

  function drawView() {
    const s = st.view;
    if (!s || !s.t.length) return;
    for (const { spec, plot } of plots) {
      const extra = overlaySeries(spec.key);
      plot.setSeries([...spec.series, ...extra]);
      const base = [s.t, ...spec.cols.map((c) => s[c])];
      const rr = extra.length ? rerunSlice(s.t[0], s.t[s.t.length - 1], extra.map((x) => x.col)) : null;
      if (!extra.length) plot.setData(base);
      else if (!rr || !rr.t.length) plot.setData([...base, ...extra.map(() => s.t.map(() => null))]);
      else plot.setData(uPlot.join([base, [rr.t, ...extra.map((x) => rr[x.col])]]));
    }
    kneeNote.hidden = !s.kneeLeftOut;
    const ov = new StrideOverlay(["torque_Nm", "foot_angle_deg"], { n: 500, maxSamples: 4096 });
    for (let i = 0; i < s.t.length; i++) ov.push(s.t[i], { torque_Nm: s.torque_Nm[i], foot_angle_deg: s.foot_angle_deg[i] }, !!s.heel_strike[i]);
    for (const b of bands) b.plot.setData(ov.bandData(b.c));
    strideNote.textContent = ov.count ? `${ov.count} strides` : "no complete stride in view";
    drawIntent();
  }

  /** The intent plot: the recorded desired and actual speed in view, and a re-run's when it ran the estimator. */
  function drawIntent() {
    const iv = st.intentView;
    const recorded = !!(iv && iv.recorded && iv.series.t && iv.series.t.length);
    const rerun = !!(st.rerun && st.rerun.intent && st.range);
    const series = [...(recorded ? INTENT_SPEC.series : []), ...(rerun ? INTENT_RERUN_SERIES : [])];
    intentDiv.hidden = !series.length;
    if (!series.length) return;
    intentPlot.setSeries(series);
    const base = recorded ? [iv.series.t, ...INTENT_SPEC.cols.map((c) => (iv.series[c] || []).map(intentValue))] : null;
    const rr = rerun ? rerunSlice(st.range[0], st.range[1], INTENT_RERUN_COLS) : null;
    const over = rr && rr.t.length ? [rr.t, ...INTENT_RERUN_COLS.map((c) => rr[c].map(intentValue))] : null;
    if (base && over) intentPlot.setData(uPlot.join([base, over]));
    else if (base) intentPlot.setData(rerun ? [...base, ...INTENT_RERUN_COLS.map(() => base[0].map(() => null))] : base);
    else if (over) intentPlot.setData(over);
    else intentPlot.setData([[], ...series.map(() => [])]);
  }

  /** What the intent card says: where its plot comes from, or the channels the trial lacks (by name). */
  function showIntentNote() {
    const i = st.intent;
    if (!i) return;
    const rerun = !!(st.rerun && st.rerun.intent);
    intentNote.dataset.state = i.recorded ? "recorded" : i.missing.length ? "missing" : "not-run";
    if (i.recorded) {
      intentNote.textContent = "As the trial's intent estimator ran: the desired speed it estimated and the centre of mass's speed, "
        + "both updated at every mid-stance. Purple markers: the detected speed changes (events)."
        + `${rerun ? " Dotted: the re-run's." : ""}`;
    } else if (i.missing.length) {
      intentNote.textContent = `No speed-change intent: this trial does not record ${listText(i.missing)}, which the intent estimator needs.`;
    } else {
      intentNote.textContent = rerun ? "The intent estimator did not run when the trial was recorded; shown: the re-run's."
        : `The intent estimator did not run when the trial was recorded: re-run it with "${estimatorLabel(INTENT || "")}" checked to see it.`;
    }
  }

  return {
    plotsBox,
    overlayCard,
    intentCard,
    draw: drawView,
    showIntentNote,
    /** The intent card's note when the trial's intent could not be loaded. */
    intentFailed(text) {
      intentNote.textContent = text;
    },
    destroy() {
      intentPlot.destroy();
      for (const { plot } of plots) plot.destroy();
      for (const b of bands) b.plot.destroy();
    },
  };
}
