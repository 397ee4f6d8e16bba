// The audit page (`#/audit`, admins): the audit trail's entries, newest first, filtered by user, action, outcome,
// target and a date range, a page at a time; a "Download CSV" link with the same filters (the whole matching trail,
// oldest first; downloading it is itself audited); and "Verify chain", which asks the server to walk the hash
// chain (`GET /api/audit/verify`) and shows whether it is intact or where it first breaks.
//
// Dates are the browser's local days: "from" is that day's local midnight, "to" includes the whole day (the
// server's `until` is the next local midnight, exclusive); both are sent as UTC instants.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { errorBox, field, fmtUtc, h, runAction, showError } from "./ui.js";

const PAGE = 50;
const OUTCOMES = [
  ["", "any outcome"],
  ["requested", "requested (before the change)"],
  ["done", "done"],
  ["failed", "failed"],
  ["refused", "refused"],
];

/** A local date ("2026-03-01", from an `<input type=date>`) plus `days`, as a UTC ISO instant; "" stays "". */
export function localDayStart(value, days = 0) {
  if (!value) return "";
  const [y, m, d] = value.split("-").map(Number);
  return new Date(y, m - 1, d + days).toISOString();
}

/**
 * The query parameters of the filters (only those set), with paging when given.
 * @returns {{user?: string, action?: string, outcome?: any, target?: string, since?: string, until?: string,
 *   limit?: number, offset?: number}}
 */
export function auditParams(filters, paging) {
  const q = {};
  for (const k of ["user", "action", "outcome", "target"]) if (filters[k]) q[k] = filters[k];
  if (filters.from) q.since = localDayStart(filters.from);
  if (filters.to) q.until = localDayStart(filters.to, 1);
  if (paging) {
    q.limit = paging.limit;
    q.offset = paging.offset;
  }
  return q;
}

/** A before/after JSON text shortened for a table cell (the full text in the cell's title). */
function jsonCell(text) {
  if (text === null || text === undefined) return h("span", { class: "hint", text: "–" });
  const short = text.length > 80 ? `${text.slice(0, 79)}…` : text;
  return h("code", { class: "audit-json", title: text, text: short });
}

function entryRow(e) {
  return h("tr", { "data-testid": "audit-row", "data-seq": e.seq, class: `audit-${e.outcome}` },
    h("td", { class: "num", text: String(e.seq) }),
    h("td", { title: e.time_utc, text: fmtUtc(e.time_utc) }),
    h("td", {}, h("strong", { text: e.user }), h("div", { class: "hint", text: e.role })),
    h("td", { "data-testid": "audit-action", text: e.action }),
    h("td", { class: "audit-target", text: e.target }),
    h("td", { "data-testid": "audit-outcome" }, h("span", { class: `audit-outcome audit-outcome-${e.outcome}`, text: e.outcome })),
    h("td", {}, jsonCell(e.before), h("span", { class: "hint", text: " → " }), jsonCell(e.after)),
    h("td", { class: "audit-detail", text: e.detail }),
    h("td", {}, h("code", { class: "audit-hash", title: `hash ${e.hash}\nprevious ${e.prev_hash}`, text: e.hash.slice(0, 10) })));
}

/** @param {HTMLElement} root */
export function mountAudit(root) {
  const st = { filters: {}, offset: 0, alive: true };
  const input = (id, props = {}) => h("input", { id, "data-testid": id, autocomplete: "off", ...props });
  const user = input("audit-user", { maxlength: 64, placeholder: "any user", autocapitalize: "none", spellcheck: "false" });
  const action = input("audit-action-filter", { maxlength: 128, placeholder: "e.g. settings. or refused" });
  const target = input("audit-target", { maxlength: 256, placeholder: "e.g. session 7" });
  const outcome = h("select", { id: "audit-outcome", "data-testid": "audit-outcome-filter" },
    ...OUTCOMES.map(([v, t]) => h("option", { value: v, text: t })));
  const from = input("audit-from", { type: "date" });
  const to = input("audit-to", { type: "date" });
  const apply = h("button", { type: "submit", class: "primary", "data-testid": "audit-apply", text: "Show" });
  const clear = h("button", { type: "button", "data-testid": "audit-clear", text: "Clear filters" });
  const csv = h("a", { class: "button", "data-testid": "audit-csv", href: api.exportAuditUrl(), download: "",
    text: "Download CSV", title: "Every entry the filters keep, oldest first (the download is itself audited)" });
  const filterError = errorBox("audit-filter-error");
  const form = h("form", { class: "card form", "data-testid": "audit-filters", novalidate: true },
    h("h2", { text: "Filters" }),
    h("div", { class: "audit-fields" },
      field("User", user), field("Action starts with", action), field("Outcome", outcome),
      field("Target starts with", target), field("From (day)", from), field("To (day, included)", to)),
    h("div", { class: "buttons" }, apply, clear, csv), filterError);

  const rows = h("tbody", { "data-testid": "audit-rows" });
  const listError = errorBox("audit-error");
  const pageInfo = h("span", { class: "hint", "data-testid": "audit-page", role: "status" });
  const newer = h("button", { type: "button", "data-testid": "audit-newer", text: "← Newer", disabled: true });
  const older = h("button", { type: "button", "data-testid": "audit-older", text: "Older →", disabled: true });
  const listCard = h("section", { class: "card", "data-testid": "audit-card" },
    h("h2", { text: "Entries (newest first)" }),
    h("div", { class: "table-scroll" }, h("table", { class: "table audit-table" },
      h("thead", {}, h("tr", {}, ...["#", "Time", "User", "Action", "Target", "Outcome", "Before → after", "Detail", "Hash"]
        .map((t) => h("th", { text: t })))),
      rows)),
    h("div", { class: "inline" }, newer, older, pageInfo), listError);

  const verify = h("button", { type: "button", "data-testid": "audit-verify", text: "Verify chain" });
  const verifyResult = h("p", { "data-testid": "audit-verify-result", role: "status", hidden: true });
  const verifyError = errorBox("audit-verify-error");
  const verifyCard = h("section", { class: "card", "data-testid": "audit-verify-card" },
    h("h2", { text: "Hash chain" }),
    h("p", { class: "hint", text: "Each entry carries the hash of the one before it: a changed, deleted or re-ordered "
      + "entry breaks the chain. Checking reads every entry (a large trail takes some seconds). Note the newest hash "
      + "somewhere else: only that shows whether the newest entries were cut off." }),
    h("div", { class: "buttons" }, verify), verifyResult, verifyError);

  function read() {
    return { user: user.value.trim(), action: action.value.trim(), outcome: outcome.value, target: target.value.trim(),
      from: from.value, to: to.value };
  }

  async function load() {
    const params = auditParams(st.filters, { limit: PAGE + 1, offset: st.offset }); // one more: is there an older page?
    csv.href = api.exportAuditUrl(auditParams(st.filters));
    try {
      const entries = await api.listAudit(params);
      if (!st.alive) return;
      const shown = entries.slice(0, PAGE);
      rows.replaceChildren(...(shown.length ? shown.map(entryRow)
        : [h("tr", {}, h("td", { class: "empty", colspan: 9, text: "No entry matches the filters." }))]));
      newer.disabled = st.offset === 0;
      older.disabled = entries.length <= PAGE;
      pageInfo.textContent = shown.length ? `entries ${st.offset + 1}–${st.offset + shown.length}` : "";
      showError(listError, null);
      showError(filterError, null);
    } catch (err) {
      if (!st.alive) return;
      showError(err.status === 422 ? filterError : listError, err);
    }
  }

  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const f = read();
    if (f.from && f.to && f.from > f.to) {
      showError(filterError, "The \"from\" day is after the \"to\" day.");
      return;
    }
    st.filters = f;
    st.offset = 0;
    runAction(apply, null, load);
  });
  clear.addEventListener("click", () => {
    for (const el of [user, action, target, from, to]) el.value = "";
    outcome.value = "";
    st.filters = {};
    st.offset = 0;
    runAction(clear, null, load);
  });
  newer.addEventListener("click", () => {
    st.offset = Math.max(0, st.offset - PAGE);
    runAction(newer, null, load);
  });
  older.addEventListener("click", () => {
    st.offset += PAGE;
    runAction(older, null, load);
  });
  verify.addEventListener("click", () => runAction(verify, verifyError, async () => {
    verifyResult.hidden = true;
    const v = await api.verifyAudit();
    verifyResult.className = v.ok ? "ok" : "error";
    verifyResult.textContent = v.ok
      ? `Chain intact: ${v.entries} entr${v.entries === 1 ? "y" : "ies"} checked.${v.last_hash ? ` Newest hash ${v.last_hash}.` : ""}`
      : `Chain broken after ${v.entries} good entries: ${v.problem}.`;
    verifyResult.hidden = false;
  }));

  const page = h("div", { class: "page audit-page" }, h("div", { class: "page-head" }, h("h1", { text: "Audit trail" })),
    fence(form, "admin", "Only an admin sees the audit trail."), fence(listCard, "admin", "Only an admin sees the audit trail."),
    fence(verifyCard, "admin", "Only an admin checks the audit trail."));
  root.append(page);
  if (listCard.dataset.fenced === undefined) load();
  return {
    unmount() {
      st.alive = false;
    },
  };
}
