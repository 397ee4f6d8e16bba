// The users page (`#/users`, admins): every account with its role, state (active, disabled, failed logins held
// back until when) and last login; add a user; change a role; disable or enable; unlock; set a new password (a reset).
// Each change is one `PATCH /api/users/{name}` (UserChange); the server ends the account's logins when its role
// changes, it is disabled or its password reset, refuses to demote or disable the last admin (409), and its
// refusals are shown next to the row in its own words. With accounts off (no login) the page says so first, and
// how to turn them on; the accounts added meanwhile are kept for then.

import * as api from "./api_client.js";
import { currentUser, fence } from "./auth.js";
import { errorBox, field, fmtUtc, h, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

const ROLES = ["admin", "clinician", "experimenter", "viewer"];
const ROLE_WORDS = {
  admin: "users, models, audit trail and everything else",
  clinician: "runs sessions, changes assistance, promotes models, sets the experimenters' limits",
  experimenter: "runs sessions and trials, annotates, uploads, re-runs; assistance within the limits",
  viewer: "reads only",
};
const NAME_RULE = new RegExp(FIELD_LIMITS.UserCreate.name.pattern);
const PASSWORD_MIN = FIELD_LIMITS.UserCreate.password.minLength;
const PASSWORD_MAX = FIELD_LIMITS.UserCreate.password.maxLength;

/** A new password typed by an admin, checked as the server will. */
function checkPassword(value) {
  if (value.length < PASSWORD_MIN) throw new ValidationError(`The password needs at least ${PASSWORD_MIN} characters.`);
  if (value.length > PASSWORD_MAX) throw new ValidationError(`The password may have at most ${PASSWORD_MAX} characters.`);
  return value;
}

/** The account's state in words: active, disabled, or failing addresses held back until when. */
export function userState(u, now = Date.now()) {
  if (u.disabled) return "disabled";
  if (u.locked_until_utc && new Date(u.locked_until_utc).getTime() > now) return `failing addresses wait until ${fmtUtc(u.locked_until_utc)}`;
  if (u.failed_logins > 0) return `active (${u.failed_logins} failed login${u.failed_logins === 1 ? "" : "s"})`;
  return "active";
}

/** With accounts off: that nobody logs in, and how to turn accounts on (docs/deployment.md). */
function accountsOffCard() {
  return h("section", { class: "card", "data-testid": "users-accounts-off" },
    h("h2", { text: "Accounts are off on this server" }),
    h("p", { text: "Nobody logs in: whoever opens gaitscope on this computer acts as \u201clocal\u201d, with every right, "
      + "and the server answers this computer only. The accounts below are kept, and used once accounts are on." }),
    h("p", { text: "To turn accounts on: add the first admin on the server, then start it again with GAITSCOPE_AUTH=true "
      + "(on a network also with TLS: see docs/deployment.md)." }),
    h("pre", { class: "hint", "data-testid": "users-accounts-on-steps",
      text: "gaitscope user add --role admin NAME   # asks for the password\nGAITSCOPE_AUTH=true gaitscope serve" }));
}

/** @param {HTMLElement} root */
export function mountUsers(root) {
  const me = currentUser();
  const rows = h("tbody", { "data-testid": "users-rows" });
  const listError = errorBox("users-error");

  // --- add a user ----------------------------------------------------------------------------------
  const name = h("input", { id: "user-add-name", "data-testid": "user-add-name", autocomplete: "off", autocapitalize: "none",
    spellcheck: "false", maxlength: 32 });
  const role = h("select", { id: "user-add-role", "data-testid": "user-add-role" },
    ...ROLES.map((r) => h("option", { value: r, text: r })));
  role.value = "viewer";
  const password = h("input", { id: "user-add-password", "data-testid": "user-add-password", type: "password",
    autocomplete: "new-password", maxlength: PASSWORD_MAX });
  const add = h("button", { type: "submit", class: "primary", "data-testid": "user-add-submit", text: "Add user" });
  const addError = errorBox("user-add-error");
  const addOk = h("p", { class: "ok", role: "status", "data-testid": "user-add-ok" });
  const addForm = h("form", { class: "card form", "data-testid": "user-add-form", novalidate: true },
    h("h2", { text: "Add a user" }),
    h("div", { class: "user-add-fields" },
      field("Name", name, "Lower case: letters, digits, _ . - (2 to 32)."),
      field("Role", role), field("Password", password, `At least ${PASSWORD_MIN} characters; they change it after.`)),
    h("div", { class: "buttons" }, add), addError, addOk);
  addForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    addOk.textContent = "";
    runAction(add, addError, async () => {
      const n = name.value.trim();
      if (!NAME_RULE.test(n)) throw new ValidationError("The name must be 2 to 32 characters, lower case, starting with a letter (letters, digits, _ . -).");
      const u = await api.addUser({ name: n, role: role.value, password: checkPassword(password.value) });
      name.value = "";
      password.value = "";
      addOk.textContent = `Added ${u.role} ${u.name}.`;
      await load();
    });
  });

  // --- the list ------------------------------------------------------------------------------------
  function row(u) {
    const me = currentUser();
    const error = errorBox("user-row-error");
    const ok = h("span", { class: "ok", role: "status", "data-testid": "user-row-ok" });
    // the row is drawn anew from the server's answer (load) once the change is made
    const change = (btn, body) => runAction(btn, error, async () => {
      await api.changeUser(u.name, body);
      await load();
    });
    const roleSel = h("select", { "data-testid": "user-role", "aria-label": `Role of ${u.name}` },
      ...ROLES.map((r) => h("option", { value: r, text: r })));
    roleSel.value = u.role;
    const roleBtn = h("button", { type: "button", class: "small", "data-testid": "user-role-apply", text: "Change role", disabled: true });
    roleSel.addEventListener("change", () => {
      roleBtn.disabled = roleSel.value === u.role;
    });
    roleBtn.addEventListener("click", () => change(roleBtn, { role: roleSel.value }));
    const toggle = h("button", { type: "button", class: "small", "data-testid": u.disabled ? "user-enable" : "user-disable",
      text: u.disabled ? "Enable" : "Disable",
      title: u.disabled ? "Let them log in again" : "They can no longer log in; their logins end now" });
    toggle.addEventListener("click", () => change(toggle, { disabled: !u.disabled }));
    const locked = !!u.locked_until_utc || u.failed_logins > 0;
    const unlock = h("button", { type: "button", class: "small", "data-testid": "user-unlock", text: "Unlock", hidden: !locked,
      title: "Forget the failed logins: addresses that failed at this name may try again at once" });
    unlock.addEventListener("click", () => change(unlock, { unlock: true }));
    const pw = h("input", { type: "password", "data-testid": "user-reset-password", autocomplete: "new-password",
      maxlength: PASSWORD_MAX, placeholder: "new password", "aria-label": `New password for ${u.name}` });
    const pwBtn = h("button", { type: "button", class: "small", "data-testid": "user-reset-apply", text: "Set password" });
    pwBtn.addEventListener("click", () => runAction(pwBtn, error, async () => {
      await api.changeUser(u.name, { password: checkPassword(pw.value), unlock: true });
      pw.value = "";
      ok.textContent = `New password set for ${u.name}; their logins ended.`;
    }));
    const self = me && me.name === u.name;
    return h("tr", { "data-testid": "user-row", "data-name": u.name, "data-role": u.role },
      h("td", { "data-testid": "user-name-cell" }, h("strong", { text: u.name }), self ? h("span", { class: "hint", text: " (you)" }) : null),
      h("td", {}, h("div", { class: "inline" }, roleSel, roleBtn), h("div", { class: "hint", text: ROLE_WORDS[u.role] })),
      h("td", { "data-testid": "user-state", text: userState(u) }),
      h("td", { "data-testid": "user-last-login", text: u.last_login_utc ? fmtUtc(u.last_login_utc) : "never" }),
      h("td", {}, h("div", { class: "inline user-actions" }, toggle, unlock),
        h("div", { class: "inline user-actions" }, pw, pwBtn), error, ok));
  }

  async function load() {
    try {
      const users = await api.listUsers();
      rows.replaceChildren(...(users.length ? users.map(row) : [h("tr", { "data-testid": "users-none" },
        h("td", { colspan: 5, class: "hint", text: "No accounts yet: add the first admin above." }))]));
      showError(listError, null);
    } catch (err) {
      showError(listError, err);
    }
  }

  const listCard = fence(h("section", { class: "card", "data-testid": "users-card" }, h("h2", { text: "Users" }),
    h("div", { class: "table-wrap" }, h("table", { class: "users-table" },
      h("thead", {}, h("tr", {}, ...["Name", "Role", "State", "Last login", "Change"].map((t) => h("th", { text: t })))),
      rows)), listError), "admin", "Only an admin sees and changes the accounts.");
  const page = h("div", { class: "page users-page" },
    h("div", { class: "page-head" }, h("h1", { text: "Users" })), me && !me.accounts ? accountsOffCard() : null,
    fence(addForm, "admin", "Only an admin adds users."), listCard);
  root.append(page);
  if (listCard.dataset.fenced === undefined) load();
  return { unmount() {} };
}
