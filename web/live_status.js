// The live page's status strip (issue #23): what a clinician decides from, in the first screen at 1024x768 and
// 1440x900 without scrolling (and first on a phone): the session's state and its Stop control, the LIVE verdict,
// whether a trial records, and the summary figures (phase, cadence, stride length, speed, incline, peak torque,
// intent). While any trial of the viewed session records, the page's header says so too (`#rec-badge`).

import * as api from "./api_client.js";
import { typing } from "./review_playback.js";
import { h } from "./ui.js";

const POLL_MS = 5000; // another screen may start or stop a recording: asked again this often (and on its events)

/** Whether a trial of the session records now, shown in the strip and in the page's header. */
export class RecordingWatch {
  /** @param {number} sessionId @param {HTMLElement | null} badge the header's recording badge */
  constructor(sessionId, badge = document.getElementById("rec-badge")) {
    this.sessionId = sessionId;
    this.badge = badge;
    this.trials = [];
    this.el = h("div", { class: "rec-state", "data-testid": "live-recording", role: "status", "aria-live": "polite",
      text: "Recording: …" });
    this._timer = setInterval(() => this.refresh(), POLL_MS);
    this.refresh();
  }

  /** Asks the server which trials of the session record. */
  async refresh() {
    try {
      const trials = await api.listTrials({ session_id: this.sessionId });
      if (this._timer === null) return; // unmounted meanwhile
      this.show(trials.filter((t) => t.status === "recording"));
    } catch {
      // the strip keeps what it showed; the recording card reports the failure
    }
  }

  /** @param {{id: number, name?: string | null}[]} recording the trials recording now */
  show(recording) {
    this.trials = recording;
    const on = recording.length > 0;
    const names = recording.map((t) => `trial ${t.id}${t.name ? ` “${t.name}”` : ""}`).join(", ");
    this.el.classList.toggle("on", on);
    this.el.title = on ? `Recording ${names}` : "No trial of this session records";
    this.el.replaceChildren(...(on ? [h("span", { class: "rec-dot", "aria-hidden": "true" }), `REC trial ${recording.map((t) => t.id).join(", ")}`] : ["Not recording"]));
    if (this.badge) {
      this.badge.hidden = !on;
      this.badge.textContent = on ? `● REC trial ${recording.map((t) => t.id).join(", ")}` : "";
      this.badge.title = on ? `Session ${this.sessionId} is recording ${names}` : "";
    }
  }

  destroy() {
    clearInterval(this._timer);
    this._timer = null;
    if (this.badge) {
      this.badge.hidden = true;
      this.badge.textContent = "";
    }
  }
}

/**
 * The strip: the session card (state, Start/Stop), the LIVE indicator, the recording state (and the header's
 * badge) and the summary; Space pauses the plots of `group` while it is mounted.
 * @param {number} sessionId @param {import("./plots.js").PlotGroup} group
 * @param {{session: HTMLElement, indicator: HTMLElement, summary: HTMLElement}} els
 * @returns {{el: HTMLElement, recording: RecordingWatch, destroy: () => void}}
 */
export function liveStatus(sessionId, group, els) {
  const recording = new RecordingWatch(sessionId);
  const stopKeys = liveKeys(group);
  const el = h("div", { class: "live-status", "data-testid": "live-status" }, els.session, els.indicator, recording.el, els.summary);
  return { el, recording, destroy: () => {
    stopKeys();
    recording.destroy();
  } };
}

/**
 * Space pauses and resumes the live plots (as in the review), not while typing in a field or on a focused
 * control (where Space presses it). Returns the function that removes the key.
 * @param {import("./plots.js").PlotGroup} group
 */
export function liveKeys(group) {
  const onKey = (ev) => {
    if (ev.key !== " " || ev.defaultPrevented || ev.ctrlKey || ev.metaKey || ev.altKey || typing(ev.target)) return;
    if (ev.target instanceof Element && ev.target.closest("button, a, summary, [role=button]")) return;
    ev.preventDefault();
    if (group.paused) group.resume();
    else group.pause();
  };
  document.addEventListener("keydown", onKey);
  return () => document.removeEventListener("keydown", onKey);
}
