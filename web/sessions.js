// Sessions page (`#/`): sessions and trials, new subject, new session (its estimators: estimator_picker.js), and the
// upload form.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { SessionEstimators } from "./estimator_picker.js";
import { mountUpload } from "./upload.js";
import { errorBox, field, fmt, fmtUtc, h, readNumber, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

// Bounds of the form fields, from the schema (sessions/schema.py via the generated wire.js).
const CODE_RE = new RegExp(FIELD_LIMITS.SubjectCreate.code.pattern);
const LEG = FIELD_LIMITS.SubjectCreate.leg_length_m;
const MASS = FIELD_LIMITS.SubjectCreate.mass_kg;
const SIM_RATE = FIELD_LIMITS.SimulatedSource.rate_hz;
const REPLAY_SPEED = FIELD_LIMITS.ReplaySource.speed;
/** "min-max", as the form's hints show a range. */
const range = (lim) => `${lim.min}-${lim.max}`;

/** Mounts the sessions page. */
export function mountSessions(root) {
  const state = { subjects: [], trials: [], alive: true };
  const subjectSelects = [];

  const sessionsBody = h("tbody", {});
  const trialsBody = h("tbody", {});
  const listError = errorBox("lists-error");

  function subjectSelect(id) {
    const sel = h("select", { id, "data-testid": id, required: true });
    subjectSelects.push(sel);
    return sel;
  }

  let subjectsSig = null;
  // Options are rebuilt only when the subjects changed, so the 5 s refresh never closes an open list.
  function fillSubjectSelects(selectId) {
    const sig = JSON.stringify(state.subjects.map((s) => [s.id, s.code]));
    if (sig === subjectsSig && selectId === undefined) return;
    subjectsSig = sig;
    for (const sel of subjectSelects) {
      const keep = selectId ?? sel.value;
      sel.replaceChildren(h("option", { value: "", text: state.subjects.length ? "— choose a subject —" : "— create a subject first —" }),
        ...state.subjects.map((s) => h("option", { value: String(s.id), text: `${s.code} (${s.side}, ${s.leg_length_m} m, ${s.mass_kg} kg)` })));
      sel.value = keep ? String(keep) : "";
    }
  }

  async function refresh(selectSubject) {
    try {
      const [subjects, sessions, trials] = await Promise.all([
        api.listSubjects(), api.listSessions(), api.listTrials(),
      ]);
      if (!state.alive) return;
      showError(listError, null);
      state.subjects = subjects;
      state.trials = trials;
      fillSubjectSelects(selectSubject);
      renderSessions(sessions);
      renderTrials(trials);
    } catch (err) {
      showError(listError, err);
    }
  }

  function renderSessions(sessions) {
    const codes = new Map(state.subjects.map((s) => [s.id, s.code]));
    sessionsBody.replaceChildren(...(sessions.length ? sessions.map((s) => h("tr", { "data-testid": "session-row", "data-id": s.id },
      h("td", {}, h("a", { href: `#/sessions/${s.id}`, "data-testid": `session-link-${s.id}`, text: `Session ${s.id}` })),
      h("td", {}, h("a", { href: `#/subjects/${s.subject_id}`, "data-testid": `subject-link-${s.subject_id}`,
        title: "The subject's page: personalized gait models", text: codes.get(s.subject_id) ?? `#${s.subject_id}` })),
      h("td", { text: s.source.kind }),
      h("td", {}, h("span", { class: `state state-${s.state}`, text: s.state })),
      h("td", { text: fmtUtc(s.created_utc) }),
      h("td", {}, h("a", { href: `#/sessions/${s.id}/summary`, "data-testid": `session-summary-${s.id}`,
        text: s.state === "running" ? "So far" : "Summary" })),
    )) : [h("tr", {}, h("td", { colspan: 6, class: "empty", text: "No sessions yet." }))]));
  }

  let trialsSig = null;
  function renderTrials(trials) {
    trialsBody.replaceChildren(...(trials.length ? trials.map((t) => h("tr", { "data-testid": "trial-row", "data-id": t.id },
      h("td", {}, h("a", { href: `#/trials/${t.id}`, "data-testid": `trial-link-${t.id}`, text: `Trial ${t.id}` })),
      h("td", { text: t.name || "–" }),
      h("td", { text: t.session_id }),
      h("td", { text: t.status }),
      h("td", { text: `${fmt(t.duration_s, 1)} s` }),
      h("td", { text: fmtUtc(t.started_utc) }),
    )) : [h("tr", {}, h("td", { colspan: 6, class: "empty", text: "No trials yet." }))]));
    const sel = root.querySelector("#replay-trial");
    const sig = JSON.stringify(trials.map((t) => [t.id, t.status]));
    if (sel && sig !== trialsSig) {
      trialsSig = sig;
      const keep = sel.value;
      sel.replaceChildren(h("option", { value: "", text: trials.length ? "— choose a trial —" : "— no trials yet —" }),
        ...trials.filter((t) => t.status !== "recording" && t.status !== "damaged").map((t) => h("option", { value: String(t.id), text: `Trial ${t.id} ${t.name}` })));
      sel.value = keep;
    }
  }

  // --- new subject ---------------------------------------------------------------------------------
  const code = h("input", { id: "subject-code", "data-testid": "subject-code", autocomplete: "off", maxlength: 32, placeholder: "e.g. S01" });
  const leg = h("input", { id: "subject-leg", "data-testid": "subject-leg", type: "number", min: LEG.min, max: LEG.max, step: 0.01, inputmode: "decimal", value: "0.9" });
  const mass = h("input", { id: "subject-mass", "data-testid": "subject-mass", type: "number", min: MASS.min, max: MASS.max, step: 0.5, inputmode: "decimal", value: "75" });
  const side = h("select", { id: "subject-side", "data-testid": "subject-side" },
    h("option", { value: "right", text: "right" }), h("option", { value: "left", text: "left" }));
  const subjectError = errorBox("subject-error");
  const subjectOk = h("p", { class: "ok", "data-testid": "subject-ok", role: "status" });
  const subjectSubmit = h("button", { type: "submit", class: "primary", "data-testid": "subject-submit", text: "Create subject" });
  const subjectForm = h("form", { class: "card form", "data-testid": "subject-form", novalidate: true },
    h("h2", { text: "New subject" }),
    field("Code (pseudonym)", code, "1-32 of A-Z a-z 0-9 _ . -"),
    field("Leg length (m)", leg, range(LEG)),
    field("Mass (kg)", mass, range(MASS)),
    field("Side of the device", side),
    subjectSubmit, subjectError, subjectOk);
  subjectForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    subjectOk.textContent = "";
    runAction(subjectSubmit, subjectError, async () => {
      const c = code.value.trim();
      if (!CODE_RE.test(c)) throw new ValidationError("Code must be 1-32 letters, digits, '_', '.' or '-', starting with a letter or digit.");
      const body = {
        code: c,
        leg_length_m: readNumber(leg, { label: "Leg length", min: LEG.min, max: LEG.max }),
        mass_kg: readNumber(mass, { label: "Mass", min: MASS.min, max: MASS.max }),
        side: side.value,
      };
      const subject = await api.createSubject(body);
      subjectOk.textContent = `Subject ${subject.code} created (id ${subject.id}).`;
      code.value = "";
      await refresh(subject.id);
    });
  });

  // --- new session ---------------------------------------------------------------------------------
  const sessSubject = subjectSelect("session-subject");
  const kindRadios = ["simulated", "replay", "device"].map((k) => h("label", { class: "choice" },
    h("input", { type: "radio", name: "source-kind", value: k, "data-testid": `source-${k}`, checked: k === "simulated" }),
    h("span", { text: { simulated: "Simulated walker", replay: "Replay a trial", device: "Live device" }[k] })));
  const simRate = h("input", { id: "sim-rate", "data-testid": "sim-rate", type: "number", min: SIM_RATE.min, max: SIM_RATE.max, step: 1, inputmode: "numeric", placeholder: "200 (default)" });
  const replayTrial = h("select", { id: "replay-trial", "data-testid": "replay-trial" });
  const replaySpeed = h("input", { id: "replay-speed", "data-testid": "replay-speed", type: "number", min: REPLAY_SPEED.min, max: REPLAY_SPEED.max, step: 0.5, value: "1", inputmode: "decimal" });
  const simBox = h("div", { class: "source-opts", "data-kind": "simulated" },
    h("p", { class: "hint", text: "Walks the default treadmill protocol (seed 000 III-E), looping." }),
    field("Sample rate (Hz, optional)", simRate, range(SIM_RATE)));
  const replayBox = h("div", { class: "source-opts", "data-kind": "replay", hidden: true },
    field("Trial", replayTrial), field("Speed (× real time)", replaySpeed, range(REPLAY_SPEED)));
  const deviceBox = h("div", { class: "source-opts", "data-kind": "device", hidden: true },
    h("p", { class: "hint", text: "The device connects to /ws/devices/{session id} and streams sensor frames." }));
  const estimators = new SessionEstimators(); // the default stack, or a choice and the one the torque follows
  const sessionError = errorBox("session-error");
  const sessionSubmit = h("button", { type: "submit", class: "primary", "data-testid": "session-submit", text: "Start session" });
  const sessionForm = h("form", { class: "card form", "data-testid": "session-form", novalidate: true },
    h("h2", { text: "New session" }),
    field("Subject", sessSubject),
    h("fieldset", { class: "choices" }, h("legend", { text: "Source" }), ...kindRadios),
    simBox, replayBox, deviceBox, estimators.el, sessionSubmit, sessionError);
  fence(subjectForm, "run");
  fence(sessionForm, "run");
  sessionForm.addEventListener("change", (ev) => {
    if (ev.target.name !== "source-kind") return;
    for (const box of [simBox, replayBox, deviceBox]) box.hidden = box.dataset.kind !== ev.target.value;
  });
  sessionForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    runAction(sessionSubmit, sessionError, async () => {
      const subjectId = Number(sessSubject.value);
      if (!subjectId) throw new ValidationError("Choose a subject (create one first).");
      const kind = sessionForm.querySelector("input[name=source-kind]:checked").value;
      /** @type {import("./wire.js").SessionCreate["source"]} */
      let source;
      if (kind === "simulated") {
        const rate = readNumber(simRate, { label: "Sample rate", min: SIM_RATE.min, max: SIM_RATE.max, optional: true });
        source = rate === null ? { kind } : { kind, rate_hz: rate };
      } else if (kind === "replay") {
        const trialId = Number(replayTrial.value);
        if (!trialId) throw new ValidationError("Choose the trial to replay.");
        source = { kind, trial_id: trialId, speed: readNumber(replaySpeed, { label: "Speed", min: REPLAY_SPEED.min, max: REPLAY_SPEED.max }) };
      } else {
        source = { kind: "device" }; // the third radio
      }
      const session = await api.createSession({ subject_id: subjectId, source, settings: estimators.settings(), start: true });
      location.hash = `#/sessions/${session.id}`;
    });
  });

  // --- lists ---------------------------------------------------------------------------------------
  const refreshBtn = h("button", { type: "button", "data-testid": "refresh", text: "Refresh", onclick: () => refresh() });
  const lists = h("div", { class: "lists" },
    h("section", { class: "card" }, h("div", { class: "card-head" }, h("h2", { text: "Sessions" }), refreshBtn),
      h("div", { class: "table-scroll" }, h("table", { class: "table", "data-testid": "sessions-table" },
        h("thead", {}, h("tr", {}, ...["Session", "Subject", "Source", "State", "Created", "Summary and report"].map((t) => h("th", { text: t })))),
        sessionsBody))),
    h("section", { class: "card" }, h("h2", { text: "Trials" }),
      h("div", { class: "table-scroll" }, h("table", { class: "table", "data-testid": "trials-table" },
        h("thead", {}, h("tr", {}, ...["Trial", "Name", "Session", "Status", "Duration", "Started"].map((t) => h("th", { text: t })))),
        trialsBody))),
    listError);

  const upload = mountUpload(subjectSelect("upload-subject"));
  root.append(h("div", { class: "page sessions-page" },
    h("h1", { text: "Sessions" }),
    h("div", { class: "forms" }, subjectForm, sessionForm, upload.el),
    lists));
  refresh();
  const timer = setInterval(() => refresh(), 5000);
  return {
    unmount() {
      state.alive = false;
      clearInterval(timer);
      upload.unmount();
    },
  };
}
