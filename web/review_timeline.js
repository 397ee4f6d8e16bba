// The review's timeline card: the torque of the whole trial (drag across it to zoom, the view's range as two
// blue lines), the zoom fields, a scrubbed cursor the leg view follows, playback and the review's keys
// (review_playback.js); a zoomed view follows the cursor to its next stretch of the trial. review.js loads a
// range (`hooks.load`) and draws it (`hooks.draw`); the view, its range and the cursor are the review's state.

import { errorText } from "./api.js";
import * as api from "./api_client.js";
import { may } from "./auth.js";
import { COLORS, markersPlugin, Plot } from "./plots.js";
import { playback, reviewKeys } from "./review_playback.js";
import { errorBox, fmt, h, readNumber, showError, ValidationError } from "./ui.js";

/**
 * @param {number} trialId
 * @param {Record<string, any>} st the review's state: `full` (the whole trial's series, read), and `view`,
 *   `intentView`, `range`, `cursor` (set here)
 * @param {{alive: () => boolean, plugins: (div: HTMLElement, plot: () => any) => any[], group: import("./plots.js").PlotGroup,
 *   load: (t0: number, t1: number) => Promise<[any, any]>, draw: () => void, redrawMarks: () => void}} hooks
 *   a time plot's plugins, the plots' group, loading range [t0, t1] (its series and intent), drawing the view,
 *   drawing the markers (the cursor among them) again
 */
export function timelineCard(trialId, st, hooks) {
  const { group } = hooks;
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
  const el = h("section", { class: "card" },
    h("h2", { text: "Timeline (drag across it to zoom)" }), timelineDiv,
    h("div", { class: "scrub-row" }, h("label", { for: "scrubber", class: "caption", text: "Cursor" }), scrubber, cursorText, h("span", { text: "s" })),
    player.el,
    h("div", { class: "inline zoom-row" }, h("label", {}, "From ", from, " s"), h("label", {}, "to ", to, " s"), zoomBtn, allBtn),
    zoomError, viewerError);

  const timelineRef = { plot: null };
  const timeline = new Plot(timelineDiv, {
    title: "Torque command, whole trial", yLabel: "N·m", height: 200, drag: true,
    series: [{ label: "torque", color: COLORS.orange }],
    // the view's range as two blue lines (the timeline's own; the events and notes are its markers)
    plugins: [...hooks.plugins(timelineDiv, () => timelineRef.plot), markersPlugin(() => (st.range && st.view !== st.full
      ? [{ t: st.range[0], color: COLORS.blue, width: 3 }, { t: st.range[1], color: COLORS.blue, width: 3 }] : []))],
    onSelect: (x0, x1) => zoom(x0, x1),
  });
  timelineRef.plot = timeline;

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
      const [s, intent] = await hooks.load(t0, t1);
      if (!hooks.alive()) return;
      st.view = s;
      st.intentView = intent;
      st.range = [t0, t1];
      group.resetX(); // the fetched range, not a zoom into the previous one
      from.value = t0.toFixed(2);
      to.value = t1.toFixed(2);
      hooks.draw();
      hooks.redrawMarks();
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
    hooks.draw();
    hooks.redrawMarks();
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
      if (showNext !== null && hooks.alive()) {
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
    hooks.redrawMarks();
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

  return {
    el,
    bounds,
    setCursor,
    /** The markers drawn on the timeline too. */
    setMarkers(list) {
      timeline.setMarkers(list);
    },
    /** The whole trial (`st.full`, just loaded) on the timeline and in view, the cursor at its start. */
    start() {
      const [T0, T1] = [st.full.t[0], st.full.t[st.full.t.length - 1]];
      Object.assign(scrubber, { min: T0, max: T1, value: T0 });
      from.min = to.min = T0;
      from.max = to.max = T1;
      timeline.setData([st.full.t, st.full.torque_Nm]);
      showAll();
      setCursor(T0, true);
    },
    destroy() {
      player.stop();
      removeKeys();
      timeline.destroy();
    },
  };
}
