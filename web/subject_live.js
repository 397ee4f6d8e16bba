// The subject page's live online fingerprint: the newest running session of the subject, followed over its
// stream (a few samples a second), and the latest point of its online fingerprint filter (`fp_gf`), or why
// there is none; and the card that draws it (`sitsCard`: where the subject sits among the training subjects, the
// live point on the scatter, the text under it).

import { openSessionStream } from "./api.js";
import { fingerprintEstimators } from "./estimators.js";
import { fingerprintScatter, gText } from "./fingerprint_plot.js";
import { fmt, h } from "./ui.js";

/** The online fingerprint filter (seed 004 GF), by its descriptor's fingerprint variant. */
const ONLINE = fingerprintEstimators("online")[0];

const LIVE_RATE_HZ = 5; // the online fingerprint moves slowly: a few samples a second are plenty

export class LiveFingerprint {
  /** @param {(scatterToo: boolean) => void} onChange called when the text (and, if `scatterToo`, the point) changed */
  constructor(onChange) {
    /** @type {{g?: number[], t?: number, why?: string} | null} the latest point, or why there is none */
    this.live = null;
    /** @type {number | null} the session followed */
    this.sessionId = null;
    this._stream = null;
    this._onChange = onChange;
  }

  /** Follows the newest running session of `sessions` (none: stops following). */
  follow(sessions) {
    const running = sessions.filter((s) => s.state === "running").sort((a, b) => b.id - a.id)[0];
    const id = running ? running.id : null;
    if (id === this.sessionId) return;
    this.close();
    if (id !== null) {
      this.sessionId = id;
      this._stream = openSessionStream(id, {
        onMessage: (msg) => this._onMessage(msg),
        onStatus: (s, info) => {
          if (s === "closed") {
            this.live = { why: `the live stream closed (${info.reason || `code ${info.code}`}).` };
            this._onChange(false);
          }
        },
      }, { maxRateHz: LIVE_RATE_HZ, batchMs: 200 });
    }
    this._onChange(true);
  }

  close() {
    if (this._stream) this._stream.close();
    this._stream = null;
    this.sessionId = null;
    this.live = null;
  }

  /** The live fingerprint in words. */
  text() {
    const l = this.live;
    return this.sessionId === null ? "No session of this subject is running: no live fingerprint."
      : !l ? `Session ${this.sessionId} is running: waiting for its online fingerprint…`
        : l.why ? `Session ${this.sessionId}: ${l.why}`
          : `Live, session ${this.sessionId} (online fingerprint filter fp_gf): ${gText(l.g)} at ${fmt(l.t, 1)} s.`;
  }

  /** @param {import("./wire.js").BrowserMessage} msg */
  _onMessage(msg) {
    if (msg.type !== "states" || !msg.states.length) return;
    const gf = ONLINE ? (msg.estimators || {})[ONLINE] : undefined;
    if (!gf) this.live = { why: "it runs no online fingerprint filter (fp_gf needs a thigh angle and a model with a fingerprint map)." };
    else if (gf.failed) this.live = { why: "its online fingerprint filter (fp_gf) has failed." };
    else {
      const cols = Object.keys(gf.columns).filter((c) => /^g\d+$/.test(c)).sort((a, b) => Number(a.slice(1)) - Number(b.slice(1)));
      let i = msg.states.length - 1;
      while (i >= 0 && cols.some((c) => gf.columns[c][i] == null)) i--;
      if (i < 0 || !cols.length) return;
      this.live = { g: cols.map((c) => gf.columns[c][i]), t: msg.states[i].t };
    }
    this._onChange(true);
  }
}

/**
 * The "where the subject sits" card: the subject's versions among the training subjects, and the live point.
 * @param {LiveFingerprint} live
 */
export function sitsCard(live) {
  const scatterBox = h("div", { class: "fp-scatter" });
  // not a live region: it changes five times a second (the plot's label says where the dot is)
  const liveText = h("p", { class: "hint", "data-testid": "fp-live-text" });
  const el = h("section", { class: "card", "data-testid": "sits-card" }, h("h2", { text: "Where the subject sits" }), scatterBox,
    h("ul", { class: "fp-legend", "aria-hidden": "true" }, h("li", {}, h("span", { class: "dot dot-cohort" }), "training subjects"),
      h("li", {}, h("span", { class: "dot dot-version" }), "this subject's versions (active ringed)"),
      h("li", {}, h("span", { class: "dot dot-live" }), "live online fingerprint")), liveText);
  return {
    el,
    /** The scatter of `fps` (the subject's fingerprints; null: not loaded yet) for subject `code`. */
    renderScatter(fps, code) {
      if (!fps) return;
      if (!fps.components) {
        scatterBox.replaceChildren(h("p", { class: "hint", text: "The model has no fingerprint map: there is nothing to place the subject in." }));
        return;
      }
      scatterBox.replaceChildren(fingerprintScatter(fps, code, live.live));
    },
    renderLive() {
      liveText.textContent = live.text();
    },
  };
}
