// What happened to the live page's session once its stream cannot go on: stopped by a server restart,
// stopped from another screen, ended by itself or failed, said in plain words, with a button that starts a
// new session for the same subject with the same source and settings.

import * as api from "./api_client.js";
import { errorBox, h, runAction } from "./ui.js";

const clock = (iso) => (iso ? new Date(iso).toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit" }) : "");

/**
 * The sentence for a session that is no longer running.
 * @param {object} session a `Session` @param {object[]} events its events, oldest first
 * @param {boolean} serverWasLost the page lost the server meanwhile (its socket could not reconnect)
 */
export function whatHappened(session, events, serverWasLost) {
  const when = clock(session.stopped_utc);
  const at = when ? ` at ${when}` : "";
  const system = [...events].reverse().find((e) => e.kind === "system" && /^(server restarted|session (stopped|failed))/.test(e.text));
  if (system && system.text.startsWith("server restarted")) return `This session was stopped by a server restart${at}.`;
  if (session.state === "failed") return `This session failed${at}${system ? `: ${system.text.replace(/^session failed: /, "")}` : ""}.`;
  if (serverWasLost) return `This session was stopped when the server restarted${at}.`;
  if (system) return `This session ended${at}: ${system.text.replace(/^session stopped: /, "")}.`;
  if (session.state === "created") return "This session has not been started.";
  return `This session was stopped${at} (from this or another screen).`;
}

/** The banner (hidden until `show`). */
export function sessionEndBanner() {
  const text = h("p", { "data-testid": "session-ended-text" });
  const error = errorBox("session-restart-error");
  const again = h("button", { type: "button", class: "primary", "data-testid": "session-restart",
    text: "Start a new session: same subject and settings" });
  const summary = h("a", { class: "button", "data-testid": "session-summary-link", text: "Session summary and report" });
  const el = h("section", { class: "card session-ended", role: "alert", "data-testid": "session-ended", hidden: true },
    h("h2", { text: "The session is not running" }), text, h("div", { class: "buttons" }, summary, again), error);
  let session = null;
  again.addEventListener("click", () => runAction(again, error, async () => {
    const { subject_id: subjectId, source, settings } = session;
    const created = await api.createSession({ subject_id: subjectId, source, settings, start: true });
    location.hash = `#/sessions/${created.id}`;
  }));
  return {
    el,
    /** Says what happened to `s` (not running); `events` oldest first. */
    show(s, events, serverWasLost) {
      session = s;
      summary.href = `#/sessions/${s.id}/summary`;
      text.textContent = whatHappened(s, events, serverWasLost);
      again.hidden = s.source.kind === "upload";
      el.hidden = false;
    },
    hide() {
      el.hidden = true;
    },
  };
}
