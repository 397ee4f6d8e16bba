// Subjects page (`#/subjects`): every subject, searchable and sortable, with each one's sessions and trials (dates,
// durations, states) and links to a session's summary, its live view and each trial's review. Trial names are
// unique within a session (the server refuses a second trial of the same name). A trial still recording is shown as
// such, with its length so far (the server counts it live), never as "nothing recorded".

import * as api from "./api_client.js";
import { fmtDuration, plural, sessionSeconds, SOURCE_WORDS, STATE_WORDS, TRIAL_WORDS } from "./people_format.js";
import { errorBox, field, fmtUtc, h, showError } from "./ui.js";

const POLL_MS = 5000;
const SORTS = {
  code: { label: "Code (A to Z)", cmp: (a, b) => a.subject.code.localeCompare(b.subject.code, undefined, { numeric: true }) },
  recent: { label: "Most recent session first", cmp: (a, b) => (b.last || "").localeCompare(a.last || "") || a.subject.code.localeCompare(b.subject.code) },
  sessions: { label: "Most sessions first", cmp: (a, b) => b.sessions.length - a.sessions.length || a.subject.code.localeCompare(b.subject.code) },
  newest: { label: "Newest subject first", cmp: (a, b) => b.subject.id - a.subject.id },
};

/** Per subject: its sessions (newest first), each with its trials, and the time of its latest session. */
function group(subjects, sessions, trials) {
  const bySession = new Map();
  for (const t of trials) {
    if (!bySession.has(t.session_id)) bySession.set(t.session_id, []);
    bySession.get(t.session_id).push(t);
  }
  return subjects.map((subject) => {
    const own = sessions.filter((s) => s.subject_id === subject.id).sort((a, b) => b.id - a.id)
      .map((s) => ({ session: s, trials: bySession.get(s.id) || [] }));
    const last = own.length ? own[0].session.started_utc || own[0].session.created_utc : null;
    const recorded = own.reduce((sum, x) => sum + x.trials.reduce((a, t) => a + (t.duration_s || 0), 0), 0);
    const recording = own.flatMap((x) => x.trials).filter((t) => t.status === "recording");
    return { subject, sessions: own, last, recorded, recording, trials: own.reduce((n, x) => n + x.trials.length, 0) };
  });
}

function sessionBlock(entry) {
  const s = entry.session;
  const secs = sessionSeconds(s);
  const links = [h("a", { href: `#/sessions/${s.id}/summary`, "data-testid": `summary-link-${s.id}`, text: "Summary" })];
  if (s.source.kind !== "upload") links.push(" · ", h("a", { href: `#/sessions/${s.id}`, text: s.state === "running" ? "Live view" : "Session page" }));
  // names are unique within a session; a database from before that rule may hold the same name twice: said so
  const uses = new Map();
  for (const t of entry.trials) uses.set(t.name.toLowerCase(), (uses.get(t.name.toLowerCase()) || 0) + 1);
  const trials = entry.trials.length
    ? h("ul", { class: "trial-list" }, ...entry.trials.map((t) => h("li", { "data-testid": "subject-trial", "data-id": t.id },
      h("a", { href: `#/trials/${t.id}`, text: t.name || `Trial ${t.id}` }),
      t.status === "recording"
        ? h("span", { class: "hint", "data-testid": "trial-recording",
          text: ` · ${fmtUtc(t.started_utc)} · recording now, ${fmtDuration(t.duration_s)} so far` })
        : h("span", { class: "hint", text: ` · ${fmtUtc(t.started_utc)} · ${fmtDuration(t.duration_s)} · ${TRIAL_WORDS[t.status] || t.status}` }),
      uses.get(t.name.toLowerCase()) > 1 ? h("span", { class: "people-dup", "data-testid": "trial-name-twice",
        text: ` · another trial of this session has this name (trial ${t.id} here)` }) : null)))
    : h("p", { class: "hint", text: "No trial recorded." });
  return h("li", { class: "people-session", "data-testid": "subject-session", "data-id": s.id },
    h("div", { class: "people-session-head" },
      h("strong", { text: `Session ${s.id}` }),
      h("span", { class: `state state-${s.state}`, text: STATE_WORDS[s.state] || s.state }),
      h("span", { text: SOURCE_WORDS[s.source.kind] || s.source.kind }),
      h("span", { "data-testid": "session-date", text: fmtUtc(s.started_utc || s.created_utc) }),
      h("span", { "data-testid": "session-duration", text: secs === null ? "not started" : fmtDuration(secs) }),
      h("span", { class: "links" }, ...links)),
    trials);
}

/** What the subject has recorded: so much, so much so far while a trial records, or nothing yet. */
function recordedText(g) {
  if (g.recording.length) return `${fmtDuration(g.recorded)} recorded so far`;
  return g.recorded > 0 ? `${fmtDuration(g.recorded)} recorded` : "nothing recorded yet";
}

function subjectCard(g, open) {
  const s = g.subject;
  const details = h("details", { class: "people-sessions", "data-testid": "subject-details", open },
    h("summary", { text: `Sessions and trials (${plural(g.sessions.length, "session")}, ${plural(g.trials, "trial")})` }),
    g.sessions.length ? h("ul", { class: "people-session-list" }, ...g.sessions.map(sessionBlock))
      : h("p", { class: "hint", text: "No session yet: start one on the sessions page." }));
  return h("li", { class: "card people-subject", "data-testid": "subject-row", "data-code": s.code, "data-id": s.id },
    h("div", { class: "people-subject-head" },
      h("h2", {}, h("a", { href: `#/subjects/${s.id}`, "data-testid": "subject-code", text: s.code })),
      h("span", { text: `${s.side} side · leg ${s.leg_length_m} m · ${s.mass_kg} kg` }),
      h("span", { "data-testid": "subject-last", text: g.last ? `last session ${fmtUtc(g.last)}` : "no session yet" }),
      g.recording.length ? h("span", { class: "state state-running", "data-testid": "subject-recording",
        text: `recording now (trial ${g.recording.map((t) => t.id).join(", ")})` }) : null,
      h("span", { "data-testid": "subject-recorded", text: recordedText(g) })),
    s.notes ? h("p", { class: "hint", text: s.notes }) : null,
    details);
}

export function mountSubjects(root) {
  const st = { groups: [], alive: true, sig: null, open: new Set() };
  const search = h("input", { type: "search", id: "subjects-search", "data-testid": "subjects-search", autocomplete: "off",
    placeholder: "code or notes" });
  const sort = h("select", { id: "subjects-sort", "data-testid": "subjects-sort" },
    ...Object.entries(SORTS).map(([k, v]) => h("option", { value: k, text: v.label })));
  const count = h("p", { class: "hint", "data-testid": "subjects-count", "aria-live": "polite" });
  const list = h("ul", { class: "people-list", "data-testid": "subjects-list" });
  const error = errorBox("subjects-error");

  function render() {
    const q = search.value.trim().toLowerCase();
    const shown = st.groups.filter((g) => !q || g.subject.code.toLowerCase().includes(q) || (g.subject.notes || "").toLowerCase().includes(q))
      .sort(SORTS[sort.value].cmp);
    // keep what the user opened across refreshes
    for (const d of list.querySelectorAll("li.people-subject")) {
      if (d.querySelector("details").open) st.open.add(Number(d.dataset.id));
      else st.open.delete(Number(d.dataset.id));
    }
    list.replaceChildren(...shown.map((g) => subjectCard(g, st.open.has(g.subject.id))));
    count.textContent = !st.groups.length ? "No subjects yet: create one on the sessions page."
      : shown.length === st.groups.length ? `${plural(shown.length, "subject")}.`
        : `${shown.length} of ${plural(st.groups.length, "subject")} match “${search.value.trim()}”.`;
  }

  async function refresh() {
    try {
      const [subjects, sessions, trials] = await Promise.all([api.listSubjects(), api.listSessions(), api.listTrials()]);
      if (!st.alive) return;
      showError(error, null);
      const sig = JSON.stringify([subjects, sessions, trials]);
      if (sig === st.sig && !sessions.some((s) => s.state === "running")) return;
      st.sig = sig;
      st.groups = group(subjects, sessions, trials);
      render();
    } catch (err) {
      if (st.alive) showError(error, err);
    }
  }

  search.addEventListener("input", render);
  sort.addEventListener("change", render);
  root.append(h("div", { class: "page people-page" },
    h("h1", { text: "Subjects" }),
    h("div", { class: "card people-tools" }, field("Search", search), field("Sort by", sort), count),
    error, list,
    h("p", { class: "hint", text: "Trial names are unique within a session: the server refuses a second trial of the same name." })));
  refresh();
  const timer = setInterval(refresh, POLL_MS);
  return {
    unmount() {
      st.alive = false;
      clearInterval(timer);
    },
  };
}
