// "Record a calibration walk now" on the subject page (subject.js): a new trial of a running session of the subject,
// stopped after the chosen duration and handed to the Fit flow. Split out of subject.js (one concept per module).

import { ApiError, authHeaders, errorText } from "./api.js";
import * as api from "./api_client.js";
import { field, fmt, h, showError, ValidationError } from "./ui.js";

const WALK_DURATIONS_S = [20, 30, 60]; // "record a calibration walk now": 20 s is ~18 strides at 1 m/s, 8 are needed
const WALK_DEFAULT_S = 30;
const WALK_NAME = "calibration walk";
const WALK_START = "Record a calibration walk now";
const WALK_TICK_MS = 250;
const WALK_CHECK_MS = 2000; // during a walk, how often its trial is asked whether it still records

/** The walk's trial name: "calibration walk", or "calibration walk 2", 3... when the session has one (trial names
 * are unique within a session: the server refuses a name taken). */
export function walkName(trials) {
  const taken = new Set(trials.map((t) => t.name.toLowerCase()));
  let name = WALK_NAME;
  for (let n = 2; taken.has(name); n++) name = `${WALK_NAME} ${n}`;
  return name;
}

/**
 * "Record a calibration walk now" on a running session of the subject: a new trial, stopped after the chosen
 * duration and handed to `onRecorded` (the Fit flow). Cancel stops it and fits nothing, as does `stop()` (the
 * page going); the session ending or another screen stopping the recording cuts it short (`onCut`).
 *
 * A session has one recording switch (`POST /api/sessions/{id}/recording`, sessions/live/runtime.py): "start"
 * while a trial records returns that trial, "stop" stops whichever records, and a session records "trial 1"
 * from its start. So a recording under way is finished (and kept) first, a start that returns an older trial
 * is refused, and the walk is stopped only while its own trial still records.
 *
 * @param {{errorEl: HTMLElement, okEl: HTMLElement, onBusy: (busy: boolean) => void,
 *   onRecorded: (trial: object) => Promise<void>, onCut: (trial: object) => Promise<void>}} hooks
 * @returns {{el: HTMLElement, update: (props: {session: number | null, recording: object | null, enabled: boolean}) => void,
 *   stop: () => void}}
 */
export function calibrationWalk({ errorEl, okEl, onBusy, onRecorded, onCut }) {
  const duration = h("select", { id: "walk-duration", "data-testid": "walk-duration" },
    ...WALK_DURATIONS_S.map((sec) => h("option", { value: String(sec), text: `${sec} s` })));
  duration.value = String(WALK_DEFAULT_S);
  const startBtn = h("button", { type: "button", class: "primary", "data-testid": "walk-start", text: WALK_START });
  const fill = h("div", { class: "meter-fill" });
  const bar = h("div", { class: "meter", role: "progressbar", "aria-label": "Calibration walk recorded", "aria-valuemin": 0,
    "data-testid": "walk-bar" }, fill);
  const left = h("span", { class: "walk-left", "data-testid": "walk-left" });
  const cancelBtn = h("button", { type: "button", "data-testid": "walk-cancel", text: "Cancel" });
  const note = h("p", { id: "walk-note", class: "hint", "data-testid": "walk-note" });
  const controls = h("div", { class: "inline" }, field("Walk duration", duration), startBtn);
  const progress = h("div", { class: "walk-progress", "data-testid": "walk-progress", hidden: true }, bar,
    h("div", { class: "walk-row" }, left, cancelBtn));
  const el = h("div", { class: "walk", role: "group", "aria-labelledby": "walk-title walk-note", "data-testid": "walk" },
    h("h3", { id: "walk-title", text: "Or record the walk now" }), note, controls, progress);
  let props = { session: null, recording: null, enabled: false };
  let w = null; // the walk under way: {sid, seconds, trial, t0, checked, ending}
  let timer = 0;
  let alive = true;
  const recording = (sid, action, name) => api.recording(sid, action === "start" ? { action, name } : { action });
  const elapsed = () => (performance.now() - w.t0) / 1000;

  function render() {
    if (w) return; // a walk under way keeps its own text
    const { session, recording: rec, enabled } = props;
    controls.hidden = session === null;
    startBtn.disabled = !enabled;
    duration.disabled = false;
    note.textContent = session === null ? "No session of this subject is running: start one to record a calibration walk from it."
      : `Session ${session} is running: record a walk on it as a new trial, fitted as soon as it ends.`
        + (rec ? ` It is recording “${rec.name}” (trial ${rec.id}): that recording is finished, and kept, when the walk starts.` : "");
  }

  function show(t) {
    const n = Math.min(Math.floor(t), w.seconds);
    fill.style.width = `${Math.min(100, (100 * t) / w.seconds)}%`;
    if (bar.getAttribute("aria-valuenow") === String(n)) return;
    bar.setAttribute("aria-valuenow", String(n));
    bar.setAttribute("aria-valuetext", `${n} s of ${w.seconds} s`);
    left.textContent = `${n} s of ${w.seconds} s · ${w.seconds - n} s left`;
  }

  function done() {
    const focused = progress.contains(document.activeElement); // Cancel, about to be hidden
    w = null;
    clearInterval(timer);
    window.removeEventListener("pagehide", onPageHide);
    progress.hidden = true;
    cancelBtn.disabled = false;
    startBtn.textContent = WALK_START;
    onBusy(false);
    render();
    if (focused) duration.focus();
  }

  /** Stops the walk's trial if it still records; the stopped trial, or null when it no longer recorded. */
  async function stopOwn(walk) {
    const t = await api.getTrial(walk.trial.id);
    if (t.status !== "recording") return null;
    try {
      return await recording(walk.sid, "stop");
    } catch (err) {
      // 409: "session N is not running" (it ended meanwhile) or "is not recording" (stopped on another screen)
      if (err instanceof ApiError && err.status === 409) return null;
      throw err;
    }
  }

  // Closing or reloading the tab unmounts nothing: one blind stop that outlives the page (`keepalive`).
  function onPageHide() {
    if (w && w.trial && !w.ending) {
      fetch(api.recordingUrl(w.sid), { method: "POST", keepalive: true,
        headers: { "Content-Type": "application/json", ...authHeaders("POST") },
        body: JSON.stringify({ action: "stop" }) }).catch(() => {});
    }
  }

  startBtn.addEventListener("click", async () => {
    if (w || props.session === null) return;
    const walk = (w = { sid: props.session, seconds: Number(duration.value), trial: null, t0: 0, checked: 0, ending: false });
    showError(errorEl, null);
    okEl.textContent = "";
    startBtn.disabled = true;
    duration.disabled = true;
    startBtn.textContent = "Starting…";
    onBusy(true);
    try {
      const before = await api.listTrials({ session_id: walk.sid });
      if (!alive) return;
      if (before.some((t) => t.status === "recording")) {
        await recording(walk.sid, "stop").catch((err) => {
          if (!(err instanceof ApiError && err.status === 409)) throw err; // already stopped: the start says if the session ended
        });
      }
      if (!alive) return;
      walk.trial = await recording(walk.sid, "start", walkName(before));
      if (before.some((t) => t.id === walk.trial.id)) {
        walk.trial = null; // not this walk's: left alone
        throw new ValidationError(`Another screen is recording on session ${walk.sid}: nothing was started. Try again when it stops.`);
      }
      if (!alive) {
        stopOwn(walk).catch(() => {});
        return;
      }
      walk.t0 = performance.now();
      note.textContent = `Recording trial ${walk.trial.id} (“${walk.trial.name}”) on session ${walk.sid}: the subject walks steadily until the bar is full.`;
      bar.setAttribute("aria-valuemax", String(walk.seconds));
      bar.removeAttribute("aria-valuenow");
      show(0);
      controls.hidden = true;
      progress.hidden = false;
      cancelBtn.focus();
      window.addEventListener("pagehide", onPageHide);
      timer = setInterval(tick, WALK_TICK_MS);
    } catch (err) {
      if (!alive) return;
      showError(errorEl, err);
      done();
    }
  });

  function tick() {
    if (!w || w.ending) return;
    const t = elapsed();
    show(t);
    if (t >= w.seconds) finish("done");
    else if (performance.now() - w.checked > WALK_CHECK_MS) {
      const walk = w;
      walk.checked = performance.now();
      api.getTrial(walk.trial.id).then((tr) => {
        if (tr.status !== "recording" && w === walk) finish("cut");
      }, () => {}); // unreachable for a moment: the next check, or the stop, tells
    }
  }

  cancelBtn.addEventListener("click", () => finish("cancel"));

  async function finish(how) {
    const walk = w;
    if (!walk || walk.ending) return;
    walk.ending = true;
    clearInterval(timer);
    cancelBtn.disabled = true;
    const secs = Math.min(walk.seconds, Math.round(elapsed()));
    let recorded = null;
    try {
      let trial = null;
      try {
        trial = how === "cut" ? null : await stopOwn(walk);
      } catch (err) {
        throw new Error(`The calibration walk's recording could not be stopped (${errorText(err)}): it may still be recording. `
          + `Stop it in session ${walk.sid}'s live view.`);
      }
      if (!alive) return;
      if (trial === null) { // cut short: say by what, and offer what was recorded
        const [t, s] = await Promise.all([api.getTrial(walk.trial.id), api.getSession(walk.sid)]);
        if (!alive) return;
        const why = s.state === "running" ? "its recording was stopped on another screen" : `session ${walk.sid} ${s.state === "failed" ? "failed" : "ended"}`;
        await onCut(t);
        throw new ValidationError(`The calibration walk was cut short (${fmt(t.duration_s, 1)} s of ${walk.seconds} s recorded): ${why}. `
          + `Nothing was fitted; what was recorded is kept as trial ${t.id}: fit it above if the walk was steady.`);
      }
      if (how === "cancel") okEl.textContent = `Calibration walk cancelled after ${secs} s: its recording stopped (kept as trial ${trial.id}); nothing was fitted.`;
      else recorded = trial;
    } catch (err) {
      if (alive) showError(errorEl, err);
    }
    if (!alive) return;
    done();
    if (recorded) await onRecorded(recorded);
  }

  render();
  return {
    el,
    update(next) {
      props = next;
      render();
    },
    /** The page goes: a walk under way is stopped (best effort, nothing shown). */
    stop() {
      alive = false;
      clearInterval(timer);
      window.removeEventListener("pagehide", onPageHide);
      if (w && w.trial && !w.ending) {
        w.ending = true;
        stopOwn(w).catch(() => {});
      }
    },
  };
}
