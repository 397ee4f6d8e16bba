// Review (`#/trials/{id}`): a timeline of the whole trial (decimated by the server) with its events,
// zoom (server fetch of the range), a scrubbed cursor the leg view follows, the live view's plots, and a
// re-run overlaid on the original: of the estimators picked (the recorded stack by default; each one's
// outputs in its own colour), with the recorded settings (the default: what ran, setting changes
// replayed where they happened) or "what if" (the editor's settings held over the whole trial). The
// speed-change intent (seed 001) as the trial recorded it, desired vs actual speed (or the channels the trial
// lacks for it), with a re-run's overlaid when the re-run ran the intent estimator. The knee of the hip and
// knee plot is drawn only from every sample (a view the server did not decimate): see `derive`.
// Issue #12: the recorded setting changes and the review notes as labelled markers (review_markers.js),
// playback and keys (review_playback.js), notes saved with the trial (review_notes.js), A/B comparison of
// named re-runs (review_ab.js), the re-run card (review_rerun.js); a trial still recording opens with a link
// to its live session.

import { errorText } from "./api.js";
import * as api from "./api_client.js";
import { may } from "./auth.js";
import { estimatorLabel, estimatorOverlay, INTENT, listText, rerunEstimators } from "./estimators.js";
import { EventList } from "./events.js";
import { legView } from "./leg_view.js";
import { bandPlot, INTENT_SPEC, intentValue, kneeFlexion, PLOT_SPECS } from "./live.js";
import { COLORS, decimateMinMax, markersPlugin, Plot, PlotGroup, StrideOverlay, uPlot } from "./plots.js";
import { abCard } from "./review_ab.js";
import { eventMarkers, markerLabels, noteMarkers, spanShading } from "./review_markers.js";
import { notesCard } from "./review_notes.js";
import { playback, reviewKeys } from "./review_playback.js";
import { RERUN_POINTS, rerunCard } from "./review_rerun.js";
import { errorBox, fmt, fmtUtc, h, readNumber, showError, ValidationError } from "./ui.js";

const MAX_POINTS = 2000; // per request, as the server decimates
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
function derive(series, maxPoints) {
  const pct = (a) => (a || []).map((v) => (v == null ? null : v * 100));
  const decimated = (series.t || []).length >= maxPoints;
  const thigh = series.thigh_angle_deg || [];
  const shank = series.shank_angle_deg || [];
  const knee = thigh.map((v, i) => (decimated ? null : kneeFlexion(v, shank[i])));
  const some = (a) => a.some((v) => v != null);
  return { ...series, phase_pct: pct(series.phase), tbe_pct: pct(series.tbe_phase), hip_flex_deg: thigh,
    knee_flex_deg: knee, kneeLeftOut: decimated && some(thigh) && some(shank) };
}

export function mountReview(root, trialId) {
  const st = { trial: null, full: null, view: null, range: null, cursor: null, events: [], rerun: null, alive: true,
    intent: null, intentView: null, // IntentSeries of the whole trial, and of the view
    notes: [], baseSettings: null }; // review notes (ReviewAnnotation), the recorded settings
  const error = errorBox("review-error");
  const title = h("h1", { "data-testid": "review-title", text: `Trial ${trialId}` });
  const info = h("p", { class: "hint", "data-testid": "trial-info" });
  const download = h("a", { class: "button", href: api.downloadUrl(trialId), download: `gaitscope_trial${trialId}.mcap`,
    "data-testid": "download-link", text: "Download MCAP (opens in Foxglove)" });
  // events (setting changes in words), review notes, the cursor: labelled markers on every time plot, drawn
  // by the plots' groups (the review's plots share zoom, cursor and hover values; so do the A/B's)
  const marks = () => [
    ...eventMarkers(st.events),
    ...noteMarkers(st.notes),
    ...(st.cursor == null ? [] : [{ t: st.cursor, kind: "cursor", label: "" }]),
  ];
  const group = new PlotGroup();
  const abGroup = new PlotGroup();
  /** Plugins of a time plot in `div`: the notes' spans shaded, and the labels drawn kept on `div`. */
  const timePlugins = (div, plot) => [spanShading(() => st.notes), markerLabels(div, plot)];

  // --- timeline, zoom, scrubber -------------------------------------------------------------------
  const timelineDiv = h("div", { class: "plot", "data-testid": "timeline" });
  const from = h("input", { type: "number", id: "zoom-from", "data-testid": "zoom-from", step: 0.1, inputmode: "decimal" });
  const to = h("input", { type: "number", id: "zoom-to", "data-testid": "zoom-to", step: 0.1, inputmode: "decimal" });
  const zoomBtn = h("button", { type: "button", class: "primary", "data-testid": "zoom-apply", text: "Zoom" });
  const allBtn = h("button", { type: "button", "data-testid": "zoom-all", text: "Whole trial" });
  const zoomError = errorBox("zoom-error");
  const scrubber = h("input", { type: "range", id: "scrubber", "data-testid": "scrubber", min: 0, max: 1, step: 0.01, value: 0,
    "aria-label": "Cursor time" });
  const cursorText = h("span", { class: "value", "data-testid": "cursor-time", text: "–" });
  const viewerError = errorBox("viewer-error");
  const bounds = () => (st.full && st.full.t.length ? [st.full.t[0], st.full.t[st.full.t.length - 1]] : null);
  const player = playback({ cursor: () => st.cursor, setCursor: (t) => followCursor(t), bounds });
  const timelineCard = h("section", { class: "card" },
    h("h2", { text: "Timeline (drag across it to zoom)" }), timelineDiv,
    h("div", { class: "scrub-row" }, h("label", { for: "scrubber", class: "caption", text: "Cursor" }), scrubber, cursorText, h("span", { text: "s" })),
    player.el,
    h("div", { class: "inline zoom-row" }, h("label", {}, "From ", from, " s"), h("label", {}, "to ", to, " s"), zoomBtn, allBtn),
    zoomError, viewerError);

  // --- plots ------------------------------------------------------------------------------------------
  const plotsBox = h("div", { class: "plots" });
  // under the hip and knee plot, when its knee is left out (`derive`)
  const kneeNote = h("p", { class: "hint", "data-testid": "review-knee-note", hidden: true,
    text: `Knee: zoom to fewer than ${MAX_POINTS} samples to see it; a longer view keeps each angle's extremes, `
      + "which are not at the same instants." });
  const plots = PLOT_SPECS.map((spec) => {
    const div = h("div", { class: "plot", "data-testid": `review-plot-${spec.key}` });
    plotsBox.append(div, ...(spec.key === "joints" ? [kneeNote] : []));
    const entry = { spec };
    entry.plot = new Plot(div, { ...spec, group, series: [...spec.series, ...overlaySeries(spec.key)],
      plugins: timePlugins(div, () => entry.plot) });
    return entry;
  });
  // desired vs actual speed: the recorded intent, or why there is none
  const intentNote = h("p", { class: "hint", "data-testid": "review-intent-note", text: "Loading the speed-change intent…" });
  const intentDiv = h("div", { class: "plot", "data-testid": "review-plot-intent", hidden: true });
  const intentCard = h("section", { class: "card", "data-testid": "review-intent" },
    h("h2", { text: "Speed-change intent (seed 001): desired vs actual speed" }), intentNote, intentDiv);
  const intentRef = { plot: null };
  const intentPlot = new Plot(intentDiv, { ...INTENT_SPEC, group, plugins: timePlugins(intentDiv, () => intentRef.plot) });
  intentRef.plot = intentPlot;
  const strideNote = h("span", { class: "hint", "data-testid": "review-stride-count" });
  const bandT = h("div", { class: "plot" });
  const bandF = h("div", { class: "plot" });
  const overlayCard = h("section", { class: "card overlay" },
    h("div", { class: "card-head" }, h("h2", { text: "Strides in view: mean ± SD" }), strideNote),
    h("div", { class: "overlay-plots" }, bandT, bandF));

  // --- re-run (review_rerun.js): the answer is drawn by showRerun, removed by clearRerun ----------------
  const rerun = rerunCard(trialId, { alive: () => st.alive, baseSettings: () => st.baseSettings, events: () => st.events,
    show: showRerun, clear: clearRerun });

  const events = new EventList("review-events", { onSelect: (ev) => setCursor(ev.t, true) });
  const notes = notesCard(trialId, { cursor: () => st.cursor, range: bounds, onSelect: (t) => setCursor(t, true),
    onChange: (list) => {
      st.notes = list;
      redrawMarks();
    } });
  const ab = abCard(trialId, { baseSettings: () => st.baseSettings, range: () => st.range, zoomed: () => st.view !== st.full,
    group: abGroup, plugins: timePlugins });
  const recording = h("section", { class: "card still-recording", "data-testid": "review-recording", hidden: true });
  const body = h("div", { class: "review-body" }, timelineCard,
    h("div", { class: "live-grid" },
      h("div", { class: "main-col" }, plotsBox, overlayCard, intentCard),
      h("aside", { class: "side-col" }, legView(null), notes.el, rerun.el,
        h("section", { class: "card" }, h("h2", { text: "Events of the trial" }), events.el))),
    ab.el);
  root.append(h("div", { class: "page review-page" },
    h("div", { class: "page-head" }, title, download, h("a", { class: "button", href: "#/", text: "← Sessions" })),
    info, error, recording));
  // The plots and the leg view join the page once the trial is known to be reviewable (a leg view's frame
  // loaded out of sight and shown later stalls the page while it starts its 3D drawing).
  const page = root.lastElementChild;

  const timelineRef = { plot: null };
  const timeline = new Plot(timelineDiv, {
    title: "Torque command, whole trial", yLabel: "N·m", height: 200, drag: true,
    series: [{ label: "torque", color: COLORS.orange }],
    // the view's range as two blue lines (the timeline's own; the events and notes are its markers)
    plugins: [...timePlugins(timelineDiv, () => timelineRef.plot), markersPlugin(() => (st.range && st.view !== st.full
      ? [{ t: st.range[0], color: COLORS.blue, width: 3 }, { t: st.range[1], color: COLORS.blue, width: 3 }] : []))],
    onSelect: (x0, x1) => zoom(x0, x1),
  });
  timelineRef.plot = timeline;
  const bands = [
    { c: "torque_Nm", plot: bandPlot(bandT, "Torque command", "N·m", COLORS.orange, { line: "#e8a07f", band: "rgba(194,65,12,0.18)" }) },
    { c: "foot_angle_deg", plot: bandPlot(bandF, "Foot angle (measured)", "deg", COLORS.blue, { line: "#7fa6d1", band: "rgba(11,92,173,0.18)" }) },
  ];

  // --- drawing ----------------------------------------------------------------------------------------
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

  async function loadIntent(t0, t1) {
    const range = t0 == null ? {} : { t0, t1 };
    return api.trialIntent(trialId, { ...range, max_points: MAX_POINTS });
  }

  /** The markers (events, notes, cursor) drawn again in every time plot. */
  function redrawMarks() {
    const list = marks();
    group.setMarkers(list);
    abGroup.setMarkers(list);
    timeline.setMarkers(list);
  }

  // --- actions ----------------------------------------------------------------------------------------
  async function zoom(x0, x1) {
    showError(zoomError, null);
    const [T0, T1] = [st.full.t[0], st.full.t[st.full.t.length - 1]];
    const t0 = Math.max(T0, Math.min(x0, x1));
    const t1 = Math.min(T1, Math.max(x0, x1));
    if (!(t1 - t0 > 0.05)) {
      showError(zoomError, "Choose a range of at least 0.05 s inside the trial.");
      return;
    }
    try {
      const [s, intent] = await Promise.all([
        api.trialSeries(trialId, { t0, t1, max_points: MAX_POINTS }).then((x) => derive(x, MAX_POINTS)),
        st.intent && st.intent.recorded ? loadIntent(t0, t1) : Promise.resolve(st.intent),
      ]);
      if (!st.alive) return;
      st.view = s;
      st.intentView = intent;
      st.range = [t0, t1];
      group.resetX(); // the fetched range, not a zoom into the previous one
      from.value = t0.toFixed(2);
      to.value = t1.toFixed(2);
      drawView();
      redrawMarks();
    } catch (err) {
      showError(zoomError, err);
    }
  }

  function showAll() {
    group.resetX();
    st.view = st.full;
    st.intentView = st.intent;
    st.range = [st.full.t[0], st.full.t[st.full.t.length - 1]];
    from.value = st.range[0].toFixed(2);
    to.value = st.range[1].toFixed(2);
    drawView();
    redrawMarks();
  }

  zoomBtn.addEventListener("click", () => {
    try {
      const [T0, T1] = [st.full.t[0], st.full.t[st.full.t.length - 1]];
      const a = readNumber(from, { label: "From", min: +T0.toFixed(2) - 0.01, max: T1 });
      const b = readNumber(to, { label: "To", min: T0, max: +T1.toFixed(2) + 0.01 });
      if (b <= a) throw new ValidationError("'To' must be after 'From'.");
      zoom(a, b);
    } catch (err) {
      showError(zoomError, err);
    }
  });
  allBtn.addEventListener("click", () => showAll());

  // The leg view follows the cursor: one request in flight, the newest position sent next.
  let showBusy = false;
  let showNext = null;
  async function postShow(t) {
    if (!may("run")) return; // posing the shared view takes `run`: a viewer watches what others chose
    if (showBusy) {
      showNext = t;
      return;
    }
    showBusy = true;
    try {
      await api.viewerShow({ trial_id: trialId, t });
      showError(viewerError, null);
    } catch (err) {
      showError(viewerError, `The leg view could not follow the cursor: ${errorText(err)}`);
    } finally {
      showBusy = false;
      if (showNext !== null && st.alive) {
        const n = showNext;
        showNext = null;
        postShow(n);
      }
    }
  }

  function setCursor(t, moveSlider) {
    st.cursor = t;
    cursorText.textContent = fmt(t, 2);
    if (moveSlider) scrubber.value = String(t);
    redrawMarks();
    postShow(t);
  }
  scrubber.addEventListener("input", () => setCursor(Number(scrubber.value), false));

  // Playback and keys move the cursor; a zoomed view follows it to its next stretch of the trial.
  let following = false;
  function followCursor(t) {
    const b = bounds();
    if (!b) return;
    const x = Math.min(Math.max(t, b[0]), b[1]);
    setCursor(x, true);
    const r = st.range;
    if (r && st.view !== st.full && !following && (x > r[1] || x < r[0])) {
      const w = r[1] - r[0];
      const t0 = x > r[1] ? Math.min(x, b[1] - w) : Math.max(b[0], x - w);
      following = true;
      zoom(t0, t0 + w).finally(() => {
        following = false;
      });
    }
  }
  /** Zoom the view around the cursor by `factor` (0.5: in, 2: out), the whole trial at most. */
  function zoomBy(factor) {
    const b = bounds();
    if (!b || !st.range) return;
    const w = (st.range[1] - st.range[0]) * factor;
    if (w >= b[1] - b[0]) {
      showAll();
      return;
    }
    const c = st.cursor == null ? (st.range[0] + st.range[1]) / 2 : st.cursor;
    const t0 = Math.min(Math.max(b[0], c - w / 2), b[1] - w);
    zoom(t0, t0 + Math.max(w, 0.06));
  }
  const removeKeys = reviewKeys({
    toggle: () => player.toggle(),
    step: (dir, big) => followCursor((st.cursor == null ? 0 : st.cursor) + dir * (big ? 1 : 0.1)),
    zoom: zoomBy,
  });

  /** Overlays a re-run's answer (the server puts it on the recording's session times: no alignment here). */
  function showRerun(res) {
    const r = derive(res, RERUN_POINTS);
    if (!r.t || !r.t.length) throw new ValidationError("The re-run produced no samples (the trial has no raw sensor frames).");
    const names = rerunEstimators(res);
    const overlay = estimatorOverlay(names, res);
    const intent = INTENT_RERUN_COLS.length > 0 && INTENT_RERUN_COLS.every((c) => Array.isArray(res[c]));
    st.rerun = { t: r.t, cols: { ...Object.fromEntries(Object.values(RERUN_COLS).map((c) => [c, r[c]])), ...overlay.cols,
      ...(intent ? Object.fromEntries(INTENT_RERUN_COLS.map((c) => [c, res[c]])) : {}) }, series: overlay.series, intent };
    showIntentNote();
    drawView();
    return { names, drawn: overlay.drawn };
  }
  function clearRerun() {
    st.rerun = null;
    showIntentNote();
    drawView();
  }

  // --- load -------------------------------------------------------------------------------------------
  /** A trial still being recorded: say so, link its live session, and open the review once it stops. */
  function stillRecording(trial) {
    download.hidden = true;
    const live = h("a", { class: "button primary", href: `#/sessions/${trial.session_id}`, "data-testid": "review-open-live",
      text: "Open the live session" });
    const note = h("p", { "data-testid": "review-recording-note", text: `Still recording: trial ${trial.id} is being recorded `
      + `now (started ${fmtUtc(trial.started_utc)}). Watch it in its live session; this page opens the review by itself `
      + "when the recording stops." });
    recording.replaceChildren(h("h2", { text: "Still recording" }), note, h("div", { class: "buttons" }, live));
    recording.hidden = false;
    const poll = setInterval(async () => {
      if (!st.alive) return clearInterval(poll);
      try {
        const now = await api.getTrial(trialId);
        if (now.status === "recording") return;
        clearInterval(poll);
        if (!st.alive) return;
        recording.hidden = true;
        download.hidden = false;
        loadAll(now);
      } catch (err) {
        showError(error, `Could not check whether the recording has stopped: ${errorText(err)}`);
      }
    }, 2000);
    st.poll = poll;
  }

  async function loadAll(trial) {
    showError(error, null);
    page.append(body);
    api.trialEstimators(trialId).then((choices) => {
      if (st.alive) rerun.picker.set(choices);
    }).catch((err) => {
      if (st.alive) rerun.picker.failed(`The estimators of this trial could not be listed: ${errorText(err)}.`);
    });
    notes.load().catch((err) => showError(error, `The notes of this trial could not be loaded: ${errorText(err)}`));
    try {
      const [series, evs, intent] = await Promise.all([
        api.trialSeries(trialId, { max_points: MAX_POINTS }),
        api.trialEvents(trialId),
        loadIntent().catch((err) => {
          intentNote.textContent = `The speed-change intent could not be loaded: ${errorText(err)}.`;
          return null;
        }),
      ]);
      if (!st.alive) return;
      st.intent = intent;
      showIntentNote();
      st.trial = trial;
      info.textContent = `${trial.status}, ${fmt(trial.duration_s, 1)} s, ${trial.samples} samples, session ${trial.session_id}, started ${fmtUtc(trial.started_utc)}`;
      st.events = evs;
      events.add(...evs);
      rerun.showChanges();
      st.full = derive(series, MAX_POINTS);
      if (!st.full.t.length) throw new ValidationError("This trial holds no gait states to show.");
      const [T0, T1] = [st.full.t[0], st.full.t[st.full.t.length - 1]];
      Object.assign(scrubber, { min: T0, max: T1, value: T0 });
      from.min = to.min = T0;
      from.max = to.max = T1;
      timeline.setData([st.full.t, st.full.torque_Nm]);
      showAll();
      setCursor(T0, true);
      // The what-if starts from the settings the trial began with (not the session's final ones).
      try {
        st.baseSettings = await api.trialSettings(trialId);
      } catch (err) {
        // Not recorded (a log from another tool): only a what-if can run, from the session's settings.
        st.baseSettings = (await api.getSession(trial.session_id)).settings;
        rerun.notRecorded(`${errorText(err)}.`);
      }
      if (!st.alive) return;
      rerun.setBaseline(st.baseSettings);
      ab.setBaseline(st.baseSettings);
      // the torque plots' range: 0 to the trial's torque bound
      group.setContext({ max_torque_Nm: st.baseSettings.max_torque_Nm });
      abGroup.setContext({ max_torque_Nm: st.baseSettings.max_torque_Nm });
    } catch (err) {
      showError(error, err);
    }
  }

  api.getTrial(trialId).then((trial) => {
    if (!st.alive) return;
    title.textContent = `Trial ${trial.id}${trial.name ? ` · ${trial.name}` : ""}`;
    if (trial.status === "recording") stillRecording(trial);
    else loadAll(trial);
  }).catch((err) => {
    showError(error, err);
  });

  return {
    unmount() {
      st.alive = false;
      clearInterval(st.poll);
      player.stop();
      removeKeys();
      ab.destroy();
      timeline.destroy();
      intentPlot.destroy();
      for (const { plot } of plots) plot.destroy();
      for (const b of bands) b.plot.destroy();
    },
  };
}
