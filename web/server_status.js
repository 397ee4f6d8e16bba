// The header's server badge, kept live: `GET /api/health` every second. A refused connection shows the
// server as lost at once (a stopped server refuses within milliseconds); a check unanswered for
// HEALTH_TIMEOUT_MS (or answered with an error) shows it as slow, and a second one in a row as lost (a busy
// server or a busy browser is not a lost server). The checks go on, and the first answer after a loss says the server is back, and
// whether it restarted (its `instance` changed) or the network only dropped. Every change is also sent
// to the page as a `SERVER_EVENT` on `window` (`onServerChange`), so views can reconnect what they hold.

import * as api from "./api_client.js";

export const SERVER_EVENT = "gaitscope:server";
export const HEALTH_EVERY_MS = 1000;
export const HEALTH_TIMEOUT_MS = 4000;
const HIDDEN_EVERY_MS = 5000; // a tab in the background checks less often

/**
 * Calls `fn(detail)` on every change of the server's state; returns a function that stops it.
 * `detail`: `{ state: "ok" | "slow" | "lost" | "back" | "error", restarted: boolean, version, message }`;
 * `restarted`: the server answering now is another process than before (what it held is gone).
 */
export function onServerChange(fn) {
  const listener = (ev) => fn(ev.detail);
  window.addEventListener(SERVER_EVENT, listener);
  return () => window.removeEventListener(SERVER_EVENT, listener);
}

const clock = (d) => d.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit" });

/** One health check: the answer's JSON, or throws with a sentence saying what went wrong. */
async function checkHealth() {
  const ctrl = new AbortController();
  const timer = setTimeout(() => ctrl.abort(), HEALTH_TIMEOUT_MS);
  try {
    let resp;
    try {
      resp = await fetch(api.healthUrl(), { cache: "no-store", signal: ctrl.signal, headers: { Accept: "application/json" } });
    } catch {
      throw Object.assign(new Error(ctrl.signal.aborted
        ? `no answer within ${HEALTH_TIMEOUT_MS / 1000} s`
        : "it cannot be reached"), { lost: ctrl.signal.aborted ? "timeout" : "refused" });
    }
    if (!resp.ok) throw new Error(`it answered with error ${resp.status}`);
    return await resp.json();
  } finally {
    clearTimeout(timer);
  }
}

/** Keeps `el` (the header badge) saying whether the server answers; runs for the page's lifetime. */
export function watchServer(el) {
  let state = "connecting";
  let instance = null;
  let lostAt = null;
  let wasOk = "ok"; // "ok" or "back": what a slow check returns to, with its words
  let okText = "";
  let okTitle = "";

  function show(next, text, title, extra = {}) {
    el.textContent = text;
    el.title = title;
    el.dataset.state = next;
    el.classList.toggle("ok", next === "ok" || next === "back");
    el.classList.toggle("bad", next === "lost" || next === "error");
    el.classList.toggle("warn", next === "slow");
    el.classList.toggle("back", next === "back");
    if (next !== state || extra.restarted) {
      state = next;
      window.dispatchEvent(new CustomEvent(SERVER_EVENT, { detail: { state: next, message: text, ...extra } }));
    }
  }

  let timer = null;
  let busy = false;

  async function poll() {
    if (busy) return; // one check at a time; the one in flight schedules the next
    busy = true;
    clearTimeout(timer);
    const now = new Date();
    try {
      const health = await checkHealth();
      const restarted = instance !== null && health.instance !== instance;
      instance = health.instance;
      const version = `gaitscope ${health.version}`;
      if (state === "slow" && !restarted) {
        show(wasOk, okText, okTitle, { restarted: false, version: health.version });
      } else if (state === "lost" || state === "error" || restarted) {
        const what = restarted ? "the server restarted" : "the connection came back";
        const since = lostAt ? ` (lost at ${clock(lostAt)})` : "";
        show("back", `Server ok again: ${restarted ? "restarted" : "reconnected"} at ${clock(now)}`,
          `${version}. Reconnected at ${clock(now)}${since}: ${what}.`, { restarted, version: health.version });
      } else if (state === "connecting") {
        okText = `Server ok · v${health.version}`;
        okTitle = `${version}, checked every second.`;
        show("ok", okText, okTitle, { restarted: false, version: health.version });
      }
      if (state === "back") [okText, okTitle] = [el.textContent, el.title];
      wasOk = state;
      lostAt = null;
    } catch (err) {
      if (lostAt === null) lostAt = now;
      if (err.lost !== "refused" && (state === "ok" || state === "back")) {
        show("slow", "Server slow to answer…", `The server's health check at ${clock(now)} failed (${err.message}); `
          + "it is shown as lost if the next check fails too.", { restarted: false });
      } else if (err.lost) {
        show("lost", "Server lost: reconnecting…",
          `The server stopped answering at ${clock(lostAt)} (${err.message}). The page keeps trying every second.`,
          { restarted: false });
      } else {
        show("error", "Server error: retrying…", `The server's health check failed: ${err.message}.`, { restarted: false });
      }
    } finally {
      busy = false;
      timer = setTimeout(poll, document.hidden ? HIDDEN_EVERY_MS : HEALTH_EVERY_MS);
    }
  }

  document.addEventListener("visibilitychange", () => {
    if (!document.hidden) poll(); // back to the tab: check now rather than up to 5 s later
  });
  poll();
}
