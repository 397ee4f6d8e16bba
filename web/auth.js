// Who is using the dashboard (issue #13): the server's `Me` (`GET /api/auth/me`), loaded once at start by
// app.js and again after a login or logout; `currentUser()` and `may(permission)` for the views; the header's
// badge (name and role, a menu with "Change password" and "Log out"); and `fence()`, which disables a card's
// controls for a role that may not use them and says why in plain words.
//
// The server decides: every route checks the role itself (server/auth.py) and its 403 is shown where it
// happens. The UI only spares the user buttons that would be refused. With accounts off (the default on
// loopback) the server answers `local` with the admin's permissions, and nobody logs in.

import { loginHash, setCsrfToken, whenLoggedOut } from "./api.js";
import * as api from "./api_client.js";
import { h } from "./ui.js";

/** What each permission lets one do, in the words of the server's refusals (server/auth.py's DOES); only
 *  `assist_within_limits` is shorter: the UI names it to a role that holds neither assistance permission. */
export const DOES = {
  read: "see data",
  run: "run sessions and trials",
  annotate: "annotate",
  upload: "upload recordings",
  assist: "change assistance",
  assist_within_limits: "change assistance",
  promote: "promote or roll back personalized models",
  set_limits: "set the experimenters' assistance limits",
  admin: "administer users, models and the audit trail",
};

let _me = null;
const _listeners = new Set();

/** The logged-in user (`Me`: name, role, accounts, permissions, csrf_token), or null when nobody is. */
export function currentUser() {
  return _me;
}

/** Whether the logged-in user's role holds `permission` (false when nobody is logged in). */
export function may(permission) {
  return !!_me && _me.permissions.includes(permission);
}

/** Calls `fn(me)` whenever who is logged in changes (login, logout, password change). */
export function onUserChange(fn) {
  _listeners.add(fn);
  return () => _listeners.delete(fn);
}

function _set(me) {
  _me = me;
  setCsrfToken(me ? me.csrf_token : null);
  for (const fn of _listeners) fn(me);
}
whenLoggedOut(() => {
  if (_me) _set(null);
});

/**
 * Asks the server who we are. A 401 means accounts are on and nobody is logged in (null); anything else that
 * fails is thrown (the server is down: the page says so rather than asking for a password).
 */
export async function loadMe() {
  const resp = await fetch(api.meUrl(), { headers: { Accept: "application/json" }, cache: "no-store" });
  if (resp.status === 401) {
    _set(null);
    return null;
  }
  if (!resp.ok) throw new Error(`The server did not say who is logged in (error ${resp.status}).`);
  const me = await resp.json();
  _set(me);
  return me;
}

/** Logs in (the server sets the cookie); the `Me` on success, an ApiError with the server's reason otherwise. */
export async function logIn(name, password) {
  const me = await api.login({ name, password });
  _set(me);
  return me;
}

/** Ends this login and goes to the login page. */
export async function logOut() {
  try {
    await api.logout();
  } finally {
    _set(null);
    location.hash = "#/login";
  }
}

/** Forgets the login without asking the server (it already ended it, e.g. after a password change). */
export function forget() {
  _set(null);
}

/** "Your role (viewer) may not run sessions and trials." */
export function refusalReason(permission) {
  if (!_me) return "Log in first.";
  return `Your role (${_me.role}) may not ${DOES[permission] || permission}.`;
}

/**
 * Fences a card's controls off when the user may not `permission`: everything after its heading goes into a
 * disabled `<fieldset>` (every button, input and select in it stays disabled whatever the card's own code
 * sets later) and a note says why. The values stay readable. Returns the card.
 * @param {HTMLElement} card
 * @param {string} permission
 * @param {string} [reason] the note's words (default: "Your role (…) may not …")
 */
export function fence(card, permission, reason) {
  if (may(permission)) return card;
  const first = card.firstElementChild;
  const keep = first && (/^H\d$/.test(first.tagName) || first.classList.contains("card-head")) ? first : null;
  const rest = [...card.childNodes].filter((n) => n !== keep);
  const fs = h("fieldset", { class: "role-fence", disabled: true, "data-testid": "role-fence" }, ...rest);
  const note = h("p", { class: "role-note", "data-testid": "role-note", text: reason || refusalReason(permission) });
  if (keep) keep.after(note, fs);
  else card.append(note, fs);
  card.dataset.fenced = permission;
  return card;
}

/**
 * The header's badge: the user's name and role with a menu ("Change password", "Log out"); with accounts off,
 * "local (no login: this computer only)". Re-renders itself when the user changes.
 */
export function userBadge() {
  const el = h("div", { class: "user-badge", "data-testid": "user-badge" });
  function render(me) {
    el.replaceChildren();
    if (!me) {
      el.hidden = true;
      return;
    }
    el.hidden = false;
    if (!me.accounts) {
      el.append(h("span", { class: "user-local", "data-testid": "user-name", title: "Accounts are off: the server " +
        "listens on this computer only (GAITSCOPE_AUTH unset)", text: "local (no login: this computer only)" }));
      return;
    }
    const out = h("button", { type: "button", "data-testid": "menu-logout", text: "Log out" });
    out.addEventListener("click", () => {
      menu.open = false;
      logOut().catch((err) => console.warn("logout failed", err));
    });
    const menu = h("details", { class: "user-menu", "data-testid": "user-menu" },
      h("summary", { "aria-label": `Account: ${me.name}, ${me.role}` },
        h("span", { class: "user-name", "data-testid": "user-name", text: me.name }), " ",
        h("span", { class: "user-role", "data-testid": "user-role", text: me.role })),
      h("div", { class: "user-pop" },
        h("a", { href: "#/account/password", class: "button", "data-testid": "menu-password", text: "Change password",
          onclick: () => { menu.open = false; } }),
        out));
    el.append(menu);
  }
  onUserChange(render);
  render(_me);
  return el;
}

/** Where to send someone who is not logged in, keeping the page they asked for. */
export { loginHash };
