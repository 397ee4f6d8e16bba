// Review (`#/trials/{id}`): a timeline of the whole trial (decimated by the server) with its events,
// zoom (server fetch of the range), a scrubbed cursor the leg view follows, the live view's plots, and a
// re-run overlaid on the original: of the estimators picked (the recorded stack by default; each one's
// outputs in its own colour), with the recorded settings (the default: what ran, setting changes
// replayed where they happened) or "what if" (the editor's settings held over the whole trial). The
// speed-change intent (seed 001) as the trial recorded it, desired vs actual speed (or the channels the trial
// lacks for it), with a re-run's overlaid when the re-run ran the intent estimator. The knee of the hip and
// knee plot is drawn only from every sample (a view the server did not decimate): see `derive` (review_plots.js).
// Issue #12: the recorded setting changes and the review notes as labelled markers (review_markers.js),
// playback and keys (review_playback.js), notes saved with the trial (review_notes.js), A/B comparison of
// named re-runs (review_ab.js), the re-run card (review_rerun.js); a trial still recording opens with a link
// to its live session. Issue #22: the timeline card (review_timeline.js) and the plots of the view
// (review_plots.js) are their own components.

import { errorText } from "./api.js";
import * as api from "./api_client.js";
import { EventList } from "./events.js";
import { legView } from "./leg_view.js";
import { PlotGroup } from "./plots.js";
import { abCard } from "./review_ab.js";
import { eventMarkers, markerLabels, noteMarkers, spanShading } from "./review_markers.js";
import { notesCard } from "./review_notes.js";
import { derive, MAX_POINTS, reviewPlots, rerunOverlay } from "./review_plots.js";
import { exportCard } from "./report_export.js";
import { rerunCard } from "./review_rerun.js";
import { timelineCard } from "./review_timeline.js";
import { errorBox, fmt, fmtUtc, h, showError, ValidationError } from "./ui.js";

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

  // --- timeline, zoom, scrubber, playback (review_timeline.js) ---------------------------------------
  const nav = timelineCard(trialId, st, { alive: () => st.alive, plugins: timePlugins, group, draw: () => view.draw(), redrawMarks,
    load: (t0, t1) => Promise.all([
      api.trialSeries(trialId, { t0, t1, max_points: MAX_POINTS }).then((x) => derive(x, MAX_POINTS)),
      st.intent && st.intent.recorded ? loadIntent(t0, t1) : Promise.resolve(st.intent),
    ]) });
  const setCursor = nav.setCursor;

  // --- plots of the view (review_plots.js) -------------------------------------------------------------
  const view = reviewPlots(st, { group, plugins: timePlugins });

  // --- re-run (review_rerun.js): the answer is drawn by showRerun, removed by clearRerun ----------------
  const rerun = rerunCard(trialId, { alive: () => st.alive, baseSettings: () => st.baseSettings, events: () => st.events,
    show: showRerun, clear: clearRerun });

  const events = new EventList("review-events", { onSelect: (ev) => setCursor(ev.t, true) });
  const notes = notesCard(trialId, { cursor: () => st.cursor, range: nav.bounds, onSelect: (t) => setCursor(t, true),
    onChange: (list) => {
      st.notes = list;
      redrawMarks();
    } });
  const ab = abCard(trialId, { baseSettings: () => st.baseSettings, range: () => st.range, zoomed: () => st.view !== st.full,
    group: abGroup, plugins: timePlugins });
  const exports = exportCard(null, { trialId }); // this trial's PDF and CSV (issue #23)
  const recording = h("section", { class: "card still-recording", "data-testid": "review-recording", hidden: true });
  const body = h("div", { class: "review-body" }, nav.el,
    h("div", { class: "live-grid" },
      h("div", { class: "main-col" }, view.plotsBox, view.overlayCard, view.intentCard),
      h("aside", { class: "side-col" }, legView(null), notes.el, rerun.el,
        h("section", { class: "card" }, h("h2", { text: "Events of the trial" }), events.el), exports.el)),
    ab.el);
  root.append(h("div", { class: "page review-page" },
    h("div", { class: "page-head" }, title, download, h("a", { class: "button", href: "#/", text: "← Sessions" })),
    info, error, recording));
  // The plots and the leg view join the page once the trial is known to be reviewable (a leg view's frame
  // loaded out of sight and shown later stalls the page while it starts its 3D drawing).
  const page = root.lastElementChild;

  // --- the intent, the markers, the re-run's overlay ---------------------------------------------------
  async function loadIntent(t0, t1) {
    const range = t0 == null ? {} : { t0, t1 };
    return api.trialIntent(trialId, { ...range, max_points: MAX_POINTS });
  }

  /** The markers (events, notes, cursor) drawn again in every time plot. */
  function redrawMarks() {
    const list = marks();
    group.setMarkers(list);
    abGroup.setMarkers(list);
    nav.setMarkers(list);
  }

  /** Overlays a re-run's answer (review_plots.js' `rerunOverlay`). */
  function showRerun(res) {
    const { rerun, names, drawn } = rerunOverlay(res);
    st.rerun = rerun;
    view.showIntentNote();
    view.draw();
    return { names, drawn };
  }
  function clearRerun() {
    st.rerun = null;
    view.showIntentNote();
    view.draw();
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
          view.intentFailed(`The speed-change intent could not be loaded: ${errorText(err)}.`);
          return null;
        }),
      ]);
      if (!st.alive) return;
      st.intent = intent;
      view.showIntentNote();
      st.trial = trial;
      info.textContent = `${trial.status}, ${fmt(trial.duration_s, 1)} s, ${trial.samples} samples, session ${trial.session_id}, started ${fmtUtc(trial.started_utc)}`;
      st.events = evs;
      events.add(...evs);
      rerun.showChanges();
      st.full = derive(series, MAX_POINTS);
      if (!st.full.t.length) throw new ValidationError("This trial holds no gait states to show.");
      nav.start();
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
      exports.stop();
      clearInterval(st.poll);
      nav.destroy();
      ab.destroy();
      view.destroy();
    },
  };
}
