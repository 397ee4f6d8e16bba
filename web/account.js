// The login page (`#/login?next=…`) and the password page (`#/account/password`).
//
// Login: name and password, the server's refusal shown in its own words (a wrong password and an unknown name
// get the same answer; as the tries before a lockout run low it says how many are left, and a lockout says for
// how long), then back to the page the user came from. Password: the
// current one, the new one twice (at least PASSWORD_MIN characters, the server's rule from wire.js); the server
// ends every login of the account after a change, so the page sends the user to log in again with the new one.

import { ApiError } from "./api.js";
import * as api from "./api_client.js";
import { currentUser, forget, logIn } from "./auth.js";
import { errorBox, field, h, runAction, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

const PASSWORD_MIN = FIELD_LIMITS.PasswordChange.new.minLength;
const PASSWORD_MAX = FIELD_LIMITS.PasswordChange.new.maxLength;
const NAME_MAX = FIELD_LIMITS.LoginRequest.name.maxLength;

/** The page to go back to after logging in: the `next` of `#/login?next=…`, if it is one of ours. */
function nextOf(hash) {
  const q = hash.indexOf("?");
  const next = q < 0 ? null : new URLSearchParams(hash.slice(q + 1)).get("next");
  return next && next.startsWith("#/") && !next.startsWith("#/login") ? next : "#/";
}

/** What a login page says above its form, set by whoever sends the user there (e.g. after a password change). */
let _notice = "";
export function loginNotice(text) {
  _notice = text;
}

/**
 * The login page.
 * @param {HTMLElement} root
 * @param {string} hash the page's hash (`#/login?next=…`)
 */
export function mountLogin(root, hash) {
  const next = nextOf(hash);
  const me = currentUser();
  if (me && (!me.accounts || me.csrf_token)) {
    // already logged in (or nothing to log in to): straight on
    root.append(h("section", { class: "card login-card", "data-testid": "login-done" },
      h("h1", { text: "Logged in" }),
      h("p", {}, me.accounts ? `You are logged in as ${me.name} (${me.role}). ` : "Accounts are off on this server: nobody logs in. ",
        h("a", { href: next, "data-testid": "login-continue", text: "Continue" }))));
    return { unmount() {} };
  }
  const name = h("input", { id: "login-name", "data-testid": "login-name", autocomplete: "username", autocapitalize: "none",
    spellcheck: "false", maxlength: NAME_MAX, required: true, autofocus: true });
  const password = h("input", { id: "login-password", "data-testid": "login-password", type: "password",
    autocomplete: "current-password", maxlength: PASSWORD_MAX, required: true });
  const submit = h("button", { type: "submit", class: "primary", "data-testid": "login-submit", text: "Log in" });
  const error = errorBox("login-error");
  const notice = h("p", { class: "ok", role: "status", "data-testid": "login-notice", text: _notice, hidden: !_notice });
  _notice = "";
  const form = h("form", { class: "card form login-card", "data-testid": "login-form", novalidate: true },
    h("h1", { text: "Log in to gaitscope" }), notice,
    field("Name", name), field("Password", password),
    h("div", { class: "buttons" }, submit), error,
    h("p", { class: "hint", text: "Forgot the password? An admin can set a new one on the Users page." }));
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    runAction(submit, error, async () => {
      const who = name.value.trim();
      if (!who) throw new ValidationError("Write your name.");
      if (!password.value) throw new ValidationError("Write your password.");
      try {
        await logIn(who, password.value);
      } catch (err) {
        password.value = "";
        password.focus();
        if (err instanceof ApiError && err.status === 401) throw new ValidationError(`Not logged in: ${err.detail}.`);
        throw err;
      }
      location.hash = next;
    });
  });
  root.append(h("div", { class: "page login-page" }, form));
  name.focus();
  return { unmount() {} };
}

/** The password page: current, new, repeat; then a new login with the new password. */
export function mountPassword(root) {
  const me = currentUser();
  if (!me || !me.accounts) {
    root.append(h("section", { class: "card", "data-testid": "password-none" }, h("h1", { text: "Change password" }),
      h("p", { text: "Accounts are off on this server: there is no password to change." })));
    return { unmount() {} };
  }
  const input = (id, autocomplete) => h("input", { id, "data-testid": id, type: "password", autocomplete, maxlength: PASSWORD_MAX });
  const current = input("password-current", "current-password");
  const fresh = input("password-new", "new-password");
  const repeat = input("password-repeat", "new-password");
  const submit = h("button", { type: "submit", class: "primary", "data-testid": "password-submit", text: "Change password" });
  const error = errorBox("password-error");
  const form = h("form", { class: "card form login-card", "data-testid": "password-form", novalidate: true },
    h("h1", { text: `Change the password of ${me.name}` }),
    field("Current password", current), field("New password", fresh, `At least ${PASSWORD_MIN} characters.`),
    field("New password again", repeat), h("div", { class: "buttons" }, submit), error,
    h("p", { class: "hint", text: "Every login of your account ends (on every screen): you log in again with the new one." }));
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    runAction(submit, error, async () => {
      if (!current.value) throw new ValidationError("Write your current password.");
      if (fresh.value.length < PASSWORD_MIN) throw new ValidationError(`The new password needs at least ${PASSWORD_MIN} characters.`);
      if (fresh.value.length > PASSWORD_MAX) throw new ValidationError(`The new password may have at most ${PASSWORD_MAX} characters.`);
      if (fresh.value !== repeat.value) throw new ValidationError("The two new passwords differ.");
      if (fresh.value === current.value) throw new ValidationError("The new password is the same as the current one.");
      await api.changePassword({ current: current.value, new: fresh.value });
      forget();
      loginNotice("Password changed: log in with the new one.");
      location.hash = "#/login";
    });
  });
  root.append(h("div", { class: "page login-page" }, form));
  current.focus();
  return { unmount() {} };
}

