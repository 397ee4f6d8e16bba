// The 3D leg view card (the live and review pages): viser's page (`server/leg_view.py`, its own port) in an
// iframe, with a legend in plain words (viser's own panel starts minimized so the leg fills the view).
// viser's client retries a lost connection only while its iframe has the keyboard focus, so after a server
// restart it would stay frozen: when the header's health check (`server_status.js`) sees the server come
// back as another process, the card asks the server for the view's address again (it may have moved to
// another port), loads a fresh iframe, and tells the server again what to follow.

import { errorText } from "./api.js";
import * as api from "./api_client.js";
import { may } from "./auth.js";
import { onServerChange } from "./server_status.js";
import { h } from "./ui.js";

// viser lays itself out for a phone below 576 px (36em): its panel becomes a bottom sheet that opens
// expanded over the view, whatever the server asks. A narrower card (a phone, the review page's side
// column) lays the iframe out at this width and scales it down to fit: viser's desktop layout, with its
// panel minimized, and the whole leg in view.
export const MIN_LAYOUT_WIDTH = 600;

/**
 * Resolves the leg view's address for this browser: a loopback or wildcard address (the server's bind, as in a
 * container) is moved to the dashboard's host, and a dashboard served over HTTPS (its own TLS, or a proxy's,
 * which serves the view's port over TLS too) gets the view over HTTPS: a browser blocks an http:// frame in an
 * https:// page.
 */
export function viewerUrl(url) {
  const u = new URL(url);
  const loop = (host) => ["127.0.0.1", "localhost", "[::1]"].includes(host);
  const wildcard = (host) => ["0.0.0.0", "[::]"].includes(host);
  if ((loop(u.hostname) && !loop(location.hostname)) || wildcard(u.hostname)) u.hostname = location.hostname;
  if (location.protocol === "https:") u.protocol = "https:";
  return u.toString();
}

/**
 * The 3D leg view card (or why the view is missing).
 * @param {{session_id: number} | null} focus the session the view follows (the live page), sent to
 *   `POST /api/viewer/focus` on opening and after every reconnection; null when the page poses the view
 *   itself (review, `POST /api/viewer/show`).
 * @param {{onReload?: () => void}} [options] `onReload`: called once the view is loaded again after a server
 *   restart (a restarted server's view waits for data: a page that poses it, like review, poses it again).
 * @returns {HTMLElement}
 */
export function legView(focus, { onReload } = {}) {
  const frame = h("div", { class: "leg-frame" });
  const overlay = h("p", { class: "leg-overlay", "data-testid": "leg-view-overlay", role: "status", hidden: true });
  frame.append(overlay);
  const msg = h("p", { class: "hint", "data-testid": "leg-view-message" });
  const legend = h("p", { class: "hint leg-legend", hidden: true },
    h("span", { class: "swatch leg-measured", "aria-hidden": "true" }), "measured leg ",
    h("span", { class: "swatch leg-model", "aria-hidden": "true" }), "gait model's prediction (translucent). ",
    "Drag to turn the view, scroll or pinch to zoom.");
  const box = h("section", { class: "card leg-card", "data-testid": "leg-card" },
    h("h2", { text: "3D leg view" }), msg, frame, legend);
  let loads = 0;

  function fit() {
    const iframe = frame.querySelector("iframe");
    const width = frame.clientWidth;
    if (!iframe || !width) return;
    const scale = Math.min(1, width / MIN_LAYOUT_WIDTH);
    Object.assign(iframe.style, scale < 1
      ? { width: `${MIN_LAYOUT_WIDTH}px`, height: `${frame.clientHeight / scale}px`, transform: `scale(${scale})` }
      : { width: "", height: "", transform: "" });
  }
  new ResizeObserver(fit).observe(frame);

  function load() {
    const mine = ++loads; // a newer load (another reconnection) wins
    return api.viewer().then((v) => {
      if (mine !== loads) return null;
      if (!v.url) {
        msg.textContent = "The leg view is switched off on this server.";
        frame.querySelector("iframe")?.remove();
        legend.hidden = true;
        return null;
      }
      msg.textContent = "";
      // A new element, not a new `src`: a fresh viser client, whatever the old one was doing.
      const iframe = h("iframe", { title: "3D leg view", "data-testid": "leg-view", src: viewerUrl(v.url) });
      iframe.addEventListener("load", () => {
        if (mine === loads) overlay.hidden = true;
      });
      const old = frame.querySelector("iframe");
      if (old) old.replaceWith(iframe);
      else frame.prepend(iframe);
      fit();
      legend.hidden = false;
      if (mine > 1 && onReload) onReload();
      // The view is everyone's: choosing what it follows takes `run` (a viewer watches what others chose).
      return focus && may("run") && api.viewerFocus(focus);
    }).catch((err) => {
      if (mine === loads) msg.textContent = `The leg view is unavailable: ${errorText(err)}`;
    });
  }

  const stop = onServerChange((s) => {
    if (!box.isConnected) {
      stop(); // the page left: nothing to reconnect
      return;
    }
    if (s.state === "lost" || s.state === "error") {
      overlay.textContent = "The server is not answering: the leg view will come back with it.";
      overlay.hidden = !frame.querySelector("iframe");
    } else if (s.state === "back" && (s.restarted || !frame.querySelector("iframe"))) {
      overlay.textContent = "Reconnecting the leg view…";
      load();
    } else if (s.state === "back") {
      overlay.hidden = true; // the same server (and viser) all along: its socket did not drop
    }
  });
  load();
  return box;
}
