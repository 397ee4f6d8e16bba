// The live view's control panels: settings (apply / revert), recording, annotations, session start/stop.
// Every request's refusal is shown in plain words next to its control.

import { api } from "./api.js";
import { imuCalibrationCard } from "./imu_calibration.js";
import { SettingsEditor } from "./settings.js";
import { armedButton, errorBox, h, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

const ACTOR_KEY = "gaitscope.actor";

/** Who is acting (written into every event as its actor); remembered on this tablet. */
export function actorSelect() {
  const sel = h("select", { id: "actor", "data-testid": "actor", "aria-label": "Acting as" },
    h("option", { value: "clinician", text: "clinician" }), h("option", { value: "experimenter", text: "experimenter" }));
  sel.value = localStorage.getItem(ACTOR_KEY) || "clinician";
  sel.addEventListener("change", () => localStorage.setItem(ACTOR_KEY, sel.value));
  return sel;
}

function _actor() {
  return localStorage.getItem(ACTOR_KEY) || "clinician";
}

/**
 * @param {number} sessionId
 * @param {{onEvent: (ev: object) => void, onSession: (s: object) => void}} hooks
 */
export function mountControls(sessionId, hooks) {
  const base = `/api/sessions/${sessionId}`;

  // --- settings ----------------------------------------------------------------------------------
  const editor = new SettingsEditor("setting");
  const applyBtn = h("button", { type: "button", class: "primary", "data-testid": "settings-apply", text: "Apply" });
  const revertBtn = h("button", { type: "button", "data-testid": "settings-revert", text: "Revert edits" });
  const settingsError = errorBox("settings-error");
  const settingsOk = h("p", { class: "ok", role: "status", "data-testid": "settings-ok" });
  applyBtn.addEventListener("click", () => {
    settingsOk.textContent = "";
    runAction(applyBtn, settingsError, async () => {
      const changes = editor.changes();
      const names = Object.keys(changes);
      if (!names.length) throw new ValidationError("Nothing to apply: no setting differs from the session's.");
      const session = await api("PATCH", `${base}/settings`, { ...changes, actor: _actor() });
      editor.setBaseline(session.settings);
      settingsOk.textContent = `Applied: ${names.join(", ")}.`;
      hooks.onSession(session);
    });
  });
  revertBtn.addEventListener("click", () => {
    editor.revert();
    showError(settingsError, null);
    settingsOk.textContent = "";
  });
  const settingsCard = h("section", { class: "card", "data-testid": "settings-card" },
    h("h2", { text: "Assistance and estimator" }), editor.el,
    h("div", { class: "buttons" }, applyBtn, revertBtn), settingsError, settingsOk);

  // --- recording ---------------------------------------------------------------------------------
  const recName = h("input", { id: "recording-name", "data-testid": "recording-name", maxlength: FIELD_LIMITS.RecordingControl.name.maxLength, placeholder: "trial name (optional)" });
  const recStart = h("button", { type: "button", class: "primary", "data-testid": "recording-start", text: "● Start recording" });
  const recStop = h("button", { type: "button", "data-testid": "recording-stop", text: "■ Stop recording", disabled: true });
  const recStatus = h("p", { class: "status-line", "data-testid": "recording-status", "aria-live": "polite", text: "Not recording." });
  const recError = errorBox("recording-error");
  const rec = { trial: null, recording: false, running: false };
  // Called after every recording request settles (runAction re-enables the button it ran from).
  function renderRecording() {
    const { trial, recording } = rec;
    recStart.disabled = recording || !rec.running;
    recStop.disabled = !recording;
    recStatus.replaceChildren();
    if (recording) {
      recStatus.append(h("span", { class: "rec-dot", "aria-hidden": "true" }),
        `Recording trial ${trial.id}${trial.name ? ` “${trial.name}”` : ""}`);
    } else if (trial) {
      recStatus.append("Not recording. Last trial: ",
        h("a", { href: `#/trials/${trial.id}`, "data-testid": "last-trial-link", text: `trial ${trial.id}` }),
        ` (${trial.duration_s.toFixed(1)} s)`);
    } else {
      recStatus.append("Not recording.");
    }
  }
  recStart.addEventListener("click", () => runAction(recStart, recError, async () => {
    const name = recName.value.trim();
    if (name.length > 100) throw new ValidationError("The trial name may have at most 100 characters.");
    rec.trial = await api("POST", `${base}/recording`, { action: "start", name });
    rec.recording = true;
    recName.value = "";
  }).then(renderRecording));
  recStop.addEventListener("click", () => runAction(recStop, recError, async () => {
    rec.trial = await api("POST", `${base}/recording`, { action: "stop" });
    rec.recording = false;
  }).then(renderRecording));
  async function refreshRecording() {
    try {
      const trials = await api("GET", `/api/trials?session_id=${sessionId}`);
      const active = trials.find((t) => t.status === "recording");
      rec.trial = active || (trials.length ? trials.reduce((a, b) => (b.id > a.id ? b : a)) : null);
      rec.recording = !!active;
      renderRecording();
    } catch (err) {
      showError(recError, err);
    }
  }
  const recordingCard = h("section", { class: "card", "data-testid": "recording-card" }, h("h2", { text: "Recording" }),
    recName, h("div", { class: "buttons" }, recStart, recStop), recStatus, recError);

  // --- annotations -------------------------------------------------------------------------------
  const annText = h("input", { id: "annotation-text", "data-testid": "annotation-text", maxlength: FIELD_LIMITS.AnnotationCreate.text.maxLength, placeholder: "e.g. subject reports discomfort", autocomplete: "off" });
  const annAdd = h("button", { type: "submit", class: "primary", "data-testid": "annotation-add", text: "Add" });
  const annError = errorBox("annotation-error");
  const annForm = h("form", { class: "card", "data-testid": "annotation-form", novalidate: true }, h("h2", { text: "Annotation" }),
    h("div", { class: "inline" }, annText, annAdd), annError);
  annForm.addEventListener("submit", (ev) => {
    ev.preventDefault();
    runAction(annAdd, annError, async () => {
      const text = annText.value.trim();
      if (!text) throw new ValidationError("Write the annotation first.");
      if (text.length > 500) throw new ValidationError("An annotation may have at most 500 characters.");
      const event = await api("POST", `${base}/annotations`, { text, actor: _actor() });
      annText.value = "";
      hooks.onEvent(event);
    });
  });

  // --- session -----------------------------------------------------------------------------------
  const sessError = errorBox("session-control-error");
  const sessState = h("span", { class: "state", "data-testid": "session-state", text: "…" });
  const sessStartBtn = h("button", { type: "button", "data-testid": "session-start", text: "Start session", hidden: true });
  const sessStopBtn = armedButton({ class: "danger", "data-testid": "session-stop" }, "Stop session", "Tap again to stop",
    () => runAction(sessStopBtn, sessError, async () => setSession(await api("POST", `${base}/stop`))));
  sessStartBtn.addEventListener("click", () => runAction(sessStartBtn, sessError, async () => setSession(await api("POST", `${base}/start`))));
  const sessionCard = h("section", { class: "card", "data-testid": "session-card" }, h("h2", { text: "Session" }),
    h("p", {}, "State: ", sessState), h("div", { class: "buttons" }, sessStartBtn, sessStopBtn), sessError);

  function setSession(session) {
    sessState.textContent = session.state;
    sessState.className = `state state-${session.state}`;
    sessStartBtn.hidden = session.state !== "created";
    sessStopBtn.hidden = session.state !== "running";
    const running = session.state === "running";
    applyBtn.disabled = !running;
    rec.running = running;
    if (!running) rec.recording = false; // stopping a session finishes its recording
    renderRecording();
    editor.setBaseline(session.settings);
    imu.refresh();
    hooks.onSession(session);
  }

  // --- IMU calibration (sessions whose stack has IMU front ends) ---------------------------------
  const imu = imuCalibrationCard(sessionId, _actor);

  refreshRecording();
  return {
    el: h("div", { class: "controls" }, settingsCard, imu.el, recordingCard, annForm, sessionCard),
    setSession,
    /** A `SettingsMessage` (possibly another client's change). */
    setSettings(settings) {
      editor.setBaseline(settings, { fromElsewhere: true });
    },
    refreshRecording,
  };
}
