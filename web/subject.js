// Subject page (`#/subjects/{id}`): the subject's personalized gait models (seed 004's fingerprints,
// docs/dashboard.md). The versions and which one runs, promoting and rolling back, export and import
// (subject_models.js); calibrating a candidate from one of their trials, or from a walk recorded now on a running
// session of theirs (people_calibration_walk.js); comparing a version with the average model on a re-run
// (subject_compare.js); and where the subject sits among the training subjects, with the live online fingerprint
// (`fp_gf`) of a running session of theirs (subject_live.js, fingerprint_plot.js).

import { ApiError, errorText } from "./api.js";
import * as api from "./api_client.js";
import { limitsCard } from "./assistance_limits.js";
import { fence } from "./auth.js";
import { intentModelCard } from "./intent_model.js";
import { calibrationWalk } from "./people_calibration_walk.js";
import { compareCard } from "./subject_compare.js";
import { LiveFingerprint, sitsCard } from "./subject_live.js";
import { excludedText, modelsCard, rmseText } from "./subject_models.js";
import { errorBox, field, fmt, fmtUtc, h, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

// CalibrationRequest.note (sessions/schema.py), from the generated wire.js.
const TEXT_MAX = FIELD_LIMITS.CalibrationRequest.note.maxLength;
const POLL_MS = 5000; // sessions, trials and versions refreshed (another screen may record or promote)
const USABLE = (t) => t.status !== "recording" && t.status !== "damaged";

const trialLabel = (t) => `Trial ${t.id}${t.name ? ` · ${t.name}` : ""} · ${fmt(t.duration_s, 1)} s · ${fmtUtc(t.started_utc)}`;

export function mountSubject(root, subjectId) {
  const st = { subject: null, fps: null, fpsSig: null, sessions: [], trialsBySession: new Map(), trials: [], trialsSig: null,
    fitting: false, walking: false, alive: true };
  const code = () => (st.subject ? st.subject.code : `subject ${subjectId}`);
  // the live online fingerprint of the newest running session of the subject (subject_live.js)
  const live = new LiveFingerprint((scatterToo) => {
    renderLive();
    if (scatterToo) renderScatter();
  });

  // --- header ---------------------------------------------------------------------------------------
  const title = h("h1", { "data-testid": "subject-title", text: `Subject ${subjectId}` });
  const body = h("p", { class: "subject-body", "data-testid": "subject-body" });
  const pageError = errorBox("subject-page-error");

  // --- compare (subject_compare.js) ------------------------------------------------------------------------
  const cmp = compareCard(subjectId, { alive: () => st.alive });

  // --- versions: promote, roll back, export, import (subject_models.js) ------------------------------------
  const models = modelsCard(subjectId, { code, fps: () => st.fps, reload: loadModels,
    compare(v) {
      cmp.el.scrollIntoView({ block: "start" });
      cmp.compare(v, null);
    } });

  // --- calibrate ------------------------------------------------------------------------------------
  const calTrial = h("select", { id: "calibrate-trial", "data-testid": "calibrate-trial" });
  const calNote = h("input", { id: "calibrate-note", "data-testid": "calibrate-note", maxlength: TEXT_MAX, autocomplete: "off",
    placeholder: "e.g. treadmill 1.0 m/s, new shoes" });
  const calBtn = h("button", { type: "button", class: "primary", "data-testid": "calibrate-submit", text: "Fit fingerprint" });
  const calBusy = h("div", { class: "progress-row", "data-testid": "calibrate-busy", hidden: true },
    h("progress", { "aria-label": "Fitting the fingerprint" }), h("span", { class: "hint", text: "Fitting the fingerprint on the walk's strides…" }));
  const calError = errorBox("calibrate-error");
  const calOk = h("p", { class: "ok", role: "status", "data-testid": "calibrate-ok" });
  const walk = calibrationWalk({ errorEl: calError, okEl: calOk,
    onBusy(busy) {
      st.walking = busy;
      syncCalibrate();
    },
    async onRecorded(trial) {
      await chooseTrial(trial);
      await fit(trial.id);
    },
    onCut: chooseTrial });
  const calCard = h("section", { class: "card", "data-testid": "calibrate-card" }, h("h2", { text: "Calibrate" }),
    h("p", { class: "hint", text: "A steady walk of at least 8 strides (about 10 s) with a thigh sensor. The fit is stored as a "
      + "candidate: nothing runs it until it is promoted." }),
    field("Calibration walk", calTrial), field("Note (optional)", calNote), h("div", { class: "buttons" }, calBtn), walk.el, calBusy, calError, calOk);
  fence(calCard, "run");

  // --- where the subject sits, the live online fingerprint (subject_live.js) -------------------------
  const sits = sitsCard(live);
  const intent = intentModelCard(subjectId); // the speed-change intent model (intent_model.js)

  root.append(h("div", { class: "page subject-page" },
    h("div", { class: "page-head" }, title,
      h("a", { class: "button", href: "#/subjects", "data-testid": "back-to-subjects", text: "← All subjects" }),
      h("a", { class: "button", href: "#/", text: "← Sessions" })),
    body, pageError, models.el, limitsCard(subjectId), intent.el, h("div", { class: "subject-grid" }, calCard, sits.el), cmp.el));

  // --- rendering --------------------------------------------------------------------------------------
  function renderModels() {
    models.render(st.fps);
    syncCalibrate();
    cmp.setVersions(st.fps.versions);
  }

  function renderScatter() {
    sits.renderScatter(st.fps, code());
  }

  function renderLive() {
    sits.renderLive();
  }

  function fillTrialSelects() {
    const sig = JSON.stringify(st.trials.map((t) => [t.id, t.name, t.status]));
    if (sig === st.trialsSig) return;
    st.trialsSig = sig;
    const options = () => st.trials.map((t) => h("option", { value: String(t.id), text: trialLabel(t) }));
    const keepCal = calTrial.value;
    calTrial.replaceChildren(h("option", { value: "", text: st.trials.length ? "— choose a walk —" : "— no recorded walk yet: record one in a session —" }),
      ...options());
    calTrial.value = st.trials.some((t) => String(t.id) === keepCal) ? keepCal : "";
    cmp.setTrials(st.trials, options);
    intent.setTrials(st.trials, options);
  }

  // --- loading --------------------------------------------------------------------------------------------
  async function loadModels() {
    const fps = await api.listFingerprints(subjectId);
    if (!st.alive) return;
    const sig = JSON.stringify(fps);
    if (sig === st.fpsSig) return;
    st.fps = fps;
    st.fpsSig = sig;
    renderModels();
    renderScatter();
  }

  // Trials change only while their session runs, or when it stops: only those sessions' are listed again.
  async function loadTrials() {
    const sessions = await api.listSessions({ subject_id: subjectId });
    const before = new Map(st.sessions.map((s) => [s.id, s.state]));
    const stale = sessions.filter((s) => s.state === "running" || before.get(s.id) !== s.state);
    const lists = await Promise.all(stale.map((s) => api.listTrials({ session_id: s.id })));
    if (!st.alive) return;
    stale.forEach((s, i) => st.trialsBySession.set(s.id, lists[i]));
    st.sessions = sessions;
    st.trials = [...st.trialsBySession.values()].flat().filter(USABLE).sort((a, b) => b.id - a.id);
    fillTrialSelects();
    live.follow(st.sessions);
    syncCalibrate();
  }

  async function refresh() {
    try {
      await Promise.all([loadModels(), loadTrials()]);
      showError(pageError, null);
    } catch (err) {
      if (st.alive && pageError.hidden) showError(pageError, `Could not refresh the page: ${errorText(err)}`);
    }
  }

  // --- calibrate --------------------------------------------------------------------------------------------
  /** The Fit flow, from the walk chosen or just recorded: a candidate, or the server's reason (a 422) why not. */
  async function fit(trialId) {
    calOk.textContent = "";
    calBtn.textContent = "Fitting…";
    calBusy.hidden = false;
    calCard.setAttribute("aria-busy", "true");
    st.fitting = true;
    syncCalibrate();
    await runAction(calBtn, calError, async () => {
      if (!trialId) throw new ValidationError("Choose the walk to calibrate from.");
      const p = await api.calibrateFingerprint(subjectId, { trial_id: trialId, model: st.fps ? st.fps.model : "default", note: calNote.value.trim() });
      if (!st.alive) return;
      calNote.value = "";
      const left = p.strides_excluded ? ` (${excludedText(p)})` : "";
      calOk.textContent = `Candidate v${p.version} fitted from trial ${trialId}: ${p.strides_used} strides used, ${p.strides_excluded} left out${left}; `
        + `fit RMSE ${rmseText(p)} deg. Compare it with the average model, then promote it.`;
      await loadModels();
      cmp.selectVersion(p.id);
    });
    st.fitting = false;
    calBtn.textContent = "Fit fingerprint";
    calBusy.hidden = true;
    calCard.removeAttribute("aria-busy");
    syncCalibrate();
  }

  calBtn.addEventListener("click", () => fit(Number(calTrial.value)));

  /** The Fit button and the walk: one at a time, and only with a model that has a fingerprint map. */
  function syncCalibrate() {
    const can = !!(st.fps && st.fps.components);
    if (!st.fitting) calBtn.disabled = st.walking || !can; // while fitting, runAction holds it
    const sid = live.sessionId;
    const rec = sid === null ? null : (st.trialsBySession.get(sid) || []).find((t) => t.status === "recording") || null;
    walk.update({ session: sid, recording: rec, enabled: can && !st.fitting });
  }

  /** A walk just recorded (or cut short) chosen in the list, once the list has it. */
  async function chooseTrial(trial) {
    try {
      await loadTrials();
    } catch {
      return; // the list catches up at the next refresh
    }
    if (st.alive && st.trials.some((t) => t.id === trial.id)) calTrial.value = String(trial.id);
  }

  // --- start --------------------------------------------------------------------------------------------------
  renderLive();
  api.getSubject(subjectId).then((s) => {
    if (!st.alive) return;
    st.subject = s;
    title.textContent = `Subject ${s.code}`;
    body.replaceChildren(h("span", { "data-testid": "subject-leg", text: `Leg length ${fmt(s.leg_length_m, 2)} m` }), " · ",
      h("span", { "data-testid": "subject-mass", text: `mass ${fmt(s.mass_kg, 1)} kg` }), " · ", `device on the ${s.side} side`);
    renderScatter();
  }).catch((err) => {
    if (!st.alive) return;
    if (err instanceof ApiError && err.status === 404) clearInterval(timer); // no such subject: nothing to poll
    showError(pageError, err);
  });
  refresh();
  const timer = setInterval(refresh, POLL_MS);

  return {
    unmount() {
      st.alive = false;
      clearInterval(timer);
      walk.stop();
      live.close();
      cmp.destroy();
    },
  };
}
