// Entry point: the hash router (`#/`, `#/sessions/{id}`, `#/trials/{id}`, `#/subjects/{id}`) and the server badge
// (`server_status.js`: checked every second, says when the server is lost and when it is back).
// Each view is `mount(container, id) -> {unmount()}`; unmount closes sockets, timers and plots.
// Accounts (issue #13): who is logged in is loaded once at start (`auth.js`); with accounts on and nobody
// logged in, every page but `#/login` sends to the login page, remembering where the user wanted to go.

import { mountLogin, mountPassword } from "./account.js";
import { mountAudit } from "./audit.js";
import { loginHash } from "./api.js";
import * as api from "./api_client.js";
import { currentUser, loadMe, may, onUserChange, userBadge } from "./auth.js";
import { mountLive } from "./live.js";
import { mountReport } from "./report.js";
import { mountReview } from "./review.js";
import { watchServer } from "./server_status.js";
import { mountSessions } from "./sessions.js";
import { mountSubject } from "./subject.js";
import { mountSubjects } from "./subjects.js";
import { h } from "./ui.js";
import { mountUsers } from "./users.js";

/** @type {Array<[RegExp, (el: HTMLElement, m: RegExpMatchArray) => {unmount?: () => void}]>} */
const ROUTES = [
  [/^#?\/?$/, (el) => mountSessions(el)],
  [/^#\/sessions\/(\d+)$/, (el, m) => mountLive(el, Number(m[1]))],
  [/^#\/trials\/(\d+)$/, (el, m) => mountReview(el, Number(m[1]))],
  [/^#\/subjects\/(\d+)$/, (el, m) => mountSubject(el, Number(m[1]))],
  [/^#\/subjects\/?$/, (el) => mountSubjects(el)],
  [/^#\/sessions\/(\d+)\/summary$/, (el, m) => mountReport(el, Number(m[1]))],
  [/^#\/login(\?.*)?$/, (el) => mountLogin(el, location.hash)],
  [/^#\/account\/password$/, (el) => mountPassword(el)],
  [/^#\/users\/?$/, (el) => mountUsers(el)],
  [/^#\/audit\/?$/, (el) => mountAudit(el)],
];
/** Pages anyone may open without a login. */
const PUBLIC = /^#\/login(\?.*)?$/;

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
  if (!currentUser() && !PUBLIC.test(hash)) {
    location.replace(loginHash(hash)); // fires hashchange, which routes to the login page
    return;
  }
  for (const [re, mount] of ROUTES) {
    const m = hash.match(re);
    if (m) {
      current = mount(view, m);
      if (!view.contains(document.activeElement)) view.focus({ preventScroll: true }); // a page may focus its first field
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
    const live = (await api.listSessions()).find((s) => s.state === "running");
    if (live) {
      location.replace(`#/sessions/${live.id}`); // fires hashchange, which routes
      return true;
    }
  } catch (err) {
    console.warn("could not list sessions", err);
  }
  return false;
}

/** The header's parts that depend on who is logged in: the badge, and the admin's nav links. */
function showUser() {
  document.querySelector(".topbar").append(userBadge());
  const adminLinks = () => {
    for (const a of document.querySelectorAll("[data-admin-only]")) /** @type {HTMLElement} */ (a).hidden = !may("admin");
  };
  onUserChange(adminLinks);
  adminLinks();
}

async function start() {
  try {
    await loadMe();
  } catch (err) {
    const view = document.getElementById("view");
    view.replaceChildren(h("section", { class: "card", "data-testid": "start-error" }, h("h1", { text: "The server did not answer" }),
      h("p", { text: `${err.message} Reload the page when the server is back.` })));
    return;
  }
  showUser();
  window.addEventListener("hashchange", route);
  const moved = currentUser() ? await firstVisit() : false;
  if (!moved) route();
}
start();
watchServer(document.getElementById("server-status")); // live: lost and back within a second or two
