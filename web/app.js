// Entry point: the hash router (`#/`, `#/sessions/{id}`, `#/trials/{id}`, `#/subjects/{id}`) and the server badge
// (`server_status.js`: checked every second, says when the server is lost and when it is back).
// Each view is `mount(container, id) -> {unmount()}`; unmount closes sockets, timers and plots.

import { api } from "./api.js";
import { mountLive } from "./live.js";
import { mountReport } from "./report.js";
import { mountReview } from "./review.js";
import { watchServer } from "./server_status.js";
import { mountSessions } from "./sessions.js";
import { mountSubject } from "./subject.js";
import { mountSubjects } from "./subjects.js";
import { h } from "./ui.js";

const ROUTES = [
  [/^#?\/?$/, (el) => mountSessions(el)],
  [/^#\/sessions\/(\d+)$/, (el, m) => mountLive(el, Number(m[1]))],
  [/^#\/trials\/(\d+)$/, (el, m) => mountReview(el, Number(m[1]))],
  [/^#\/subjects\/(\d+)$/, (el, m) => mountSubject(el, Number(m[1]))],
  [/^#\/subjects\/?$/, (el) => mountSubjects(el)],
  [/^#\/sessions\/(\d+)\/summary$/, (el, m) => mountReport(el, Number(m[1]))],
];

let current = null;

function route() {
  const view = document.getElementById("view");
  if (current && current.unmount) {
    try {
      current.unmount();
    } catch (err) {
      console.warn("unmount failed", err);
    }
  }
  current = null;
  view.replaceChildren();
  const hash = location.hash || "#/";
  for (const [re, mount] of ROUTES) {
    const m = hash.match(re);
    if (m) {
      current = mount(view, m);
      view.focus({ preventScroll: true });
      window.scrollTo(0, 0);
      return;
    }
  }
  view.append(h("section", { class: "card" }, h("h1", { text: "Page not found" }),
    h("p", {}, "No page at ", h("code", { text: hash }), ". ", h("a", { href: "#/", text: "Back to sessions" }))));
}

// Opening the bare URL (as `gaitscope serve` prints it) goes straight to the newest running session.
async function firstVisit() {
  if (location.hash) return false;
  try {
    const live = (await api("GET", "/api/sessions")).find((s) => s.state === "running");
    if (live) {
      location.replace(`#/sessions/${live.id}`); // fires hashchange, which routes
      return true;
    }
  } catch (err) {
    console.warn("could not list sessions", err);
  }
  return false;
}

window.addEventListener("hashchange", route);
firstVisit().then((moved) => {
  if (!moved) route();
});
watchServer(document.getElementById("server-status")); // live: lost and back within a second or two
