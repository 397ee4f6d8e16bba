// The live view's control panels: settings (apply / revert / undo the last change), recording, annotations,
// session start/stop. Every change that can raise the torque on the person (a raise of the torque gain, the maximum
// torque or the intent boost, an undo that does one) asks first, naming the peak torque before and after
// (confirm_change.js, the server's torque rule); lowering never asks. Every request's refusal is
// shown in plain words next to its control. Roles (issue #13): a card whose actions the user's role may not
// take is fenced off with the reason (auth.js); an experimenter sees the subject's assistance limits next to
// the settings, and a change beyond them is refused here, before it is sent.

import * as api from "./api_client.js";
import { limitsText, loadLimits, overLimits } from "./assistance_limits.js";
import { fence, may } from "./auth.js";
import { sendByTorqueRule, torqueConfirmBox } from "./confirm_change.js";
import { describeEvent } from "./events.js";
import { imuCalibrationCard } from "./imu_calibration.js";
import { SETTING_LIMITS, SettingsEditor } from "./settings.js";
import { armedButton, errorBox, fmt, h, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

/**
 * @param {number} sessionId
 * @param {{onEvent: (ev: object) => void, onSession: (s: object) => void}} hooks
 */
export function mountControls(sessionId, hooks) {

  // --- settings ----------------------------------------------------------------------------------
  const editor = new SettingsEditor("setting", { rateLimited: true });
  const applyBtn = h("button", { type: "button", class: "primary", "data-testid": "settings-apply", text: "Apply" });
  const revertBtn = h("button", { type: "button", "data-testid": "settings-revert", text: "Revert edits" });
  const undoBtn = h("button", { type: "button", "data-testid": "settings-undo", text: "Undo last change", disabled: true });
  const undoWhat = h("p", { class: "hint", "data-testid": "settings-undo-what", text: "No change to undo yet." });
  const settingsError = errorBox("settings-error");
  const settingsOk = h("p", { class: "ok", role: "status", "data-testid": "settings-ok" });
  // a change that can raise the torque: a second, explicit step, with the peaks before and after
  const confirm = torqueConfirmBox("confirm-raise");
  const label = (k) => SETTING_LIMITS[k].label.split(":")[0];
  // an experimenter: assistance only within the subject's limits (loaded with the first session seen)
  const bounded = !may("assist") && may("assist_within_limits");
  const limitsLine = h("p", { class: "hint limits-line", "data-testid": "settings-limits", hidden: !bounded });
  const limits = { subjectId: null, value: null, loaded: false };
  async function loadSubjectLimits(subjectId) {
    if (!bounded || limits.subjectId === subjectId) return;
    limits.subjectId = subjectId;
    try {
      limits.value = await loadLimits(subjectId);
      limits.loaded = true;
      limitsLine.textContent = `Your limits for this subject (set by a clinician): ${limitsText(limits.value)}.`;
    } catch (err) {
      limitsLine.textContent = `The subject's assistance limits could not be loaded (${err.message}); the server still checks them.`;
    }
  }
  async function apply(changes) {
    if (bounded && limits.loaded) {
      const over = overLimits(changes, limits.value);
      if (over) throw new ValidationError(over);
    }
    const what = `Change ${Object.keys(changes).map((k) => `${label(k).toLowerCase()} ` +
      `${fmt(editor.baseline[k], SETTING_LIMITS[k].digits)} → ${fmt(changes[k], SETTING_LIMITS[k].digits)}`).join(", ")}`;
    const session = await sendByTorqueRule(sessionId, changes, confirm,
      (yes) => api.changeSettings(sessionId, yes ? { ...changes, confirm: true } : changes), what);
    if (!session) {
      settingsOk.textContent = "Not applied: cancelled.";
      return;
    }
    editor.setBaseline(session.settings);
    settingsOk.textContent = `Applied: ${Object.keys(changes).map(label).join(", ")}.`;
    hooks.onSession(session);
  }
  applyBtn.addEventListener("click", () => {
    settingsOk.textContent = "";
    runAction(applyBtn, settingsError, async () => {
      const changes = editor.changes();
      if (!Object.keys(changes).length) throw new ValidationError("Nothing to apply: no setting differs from the session's.");
      await apply(changes);
    });
  });
  revertBtn.addEventListener("click", () => {
    editor.revert();
    confirm.cancel();
    showError(settingsError, null);
    settingsOk.textContent = "";
  });
  undoBtn.addEventListener("click", () => {
    settingsOk.textContent = "";
    runAction(undoBtn, settingsError, async () => {
      const session = await sendByTorqueRule(sessionId, null, confirm,
        (yes) => api.undoSettings(sessionId, yes ? { confirm: true } : {}), "Undo the last change");
      if (!session) {
        settingsOk.textContent = "Not undone: cancelled.";
        return;
      }
      editor.setBaseline(session.settings);
      settingsOk.textContent = "Undone: the settings are back to what they were before the last change.";
      hooks.onSession(session);
    }).then(() => {
      undoBtn.disabled = !lastChange;
    });
  });
  let lastChange = null;
  /** The newest setting event (what "Undo" would set back). */
  function setLastChange(ev) {
    lastChange = ev;
    undoWhat.textContent = ev ? `Last change: ${describeEvent(ev).headline}.` : "No change to undo yet.";
    undoBtn.disabled = !ev || !rec.running;
  }
  const settingsCard = h("section", { class: "card", "data-testid": "settings-card" },
    h("h2", { text: "Assistance and estimator" }), limitsLine, editor.el,
    h("div", { class: "buttons" }, applyBtn, revertBtn, undoBtn), undoWhat, confirm.el, settingsError, settingsOk);

  // --- recording, annotations (below) ------------------------------------------------------------
  const recording = recordingCard(sessionId);
  const rec = recording.state;
  const annForm = annotationCard(sessionId, hooks.onEvent);

  // --- session -----------------------------------------------------------------------------------
  const sessError = errorBox("session-control-error");
  const sessState = h("span", { class: "state", "data-testid": "session-state", text: "…" });
  const sessStartBtn = h("button", { type: "button", "data-testid": "session-start", text: "Start session", hidden: true });
  const sessStopBtn = armedButton({ class: "danger", "data-testid": "session-stop" }, "Stop session", "Tap again to stop",
    () => runAction(sessStopBtn, sessError, async () => setSession(await api.stopSession(sessionId))));
  sessStartBtn.addEventListener("click", () => runAction(sessStartBtn, sessError, async () => setSession(await api.startSession(sessionId))));
  const sessionCard = h("section", { class: "card", "data-testid": "session-card" }, h("h2", { text: "Session" }),
    h("p", {}, "State: ", sessState), h("div", { class: "buttons" }, sessStartBtn, sessStopBtn), sessError);
  fence(settingsCard, "assist_within_limits");
  fence(sessionCard, "run");

  function setSession(session) {
    sessState.textContent = session.state;
    sessState.className = `state state-${session.state}`;
    sessStartBtn.hidden = session.state !== "created";
    sessStopBtn.hidden = session.state !== "running";
    const running = session.state === "running";
    applyBtn.disabled = !running;
    undoBtn.disabled = !running || !lastChange;
    rec.running = running;
    if (!running) rec.recording = false; // stopping a session finishes its recording
    recording.render();
    editor.setBaseline(session.settings);
    loadSubjectLimits(session.subject_id);
    imu.refresh();
    hooks.onSession(session);
  }

  // --- IMU calibration (sessions whose stack has IMU front ends) ---------------------------------
  const imu = imuCalibrationCard(sessionId);

  recording.refresh();
  return {
    el: h("div", { class: "controls" }, settingsCard, imu.el, recording.el, annForm, sessionCard),
    /** The cards one by one, for a page that lays them out itself. */
    cards: { settings: settingsCard, imu: imu.el, recording: recording.el, annotation: annForm, session: sessionCard },
    editor,
    setSession,
    setLastChange,
    /** A `SettingsMessage` (possibly another client's change). */
    setSettings(settings) {
      editor.setBaseline(settings, { fromElsewhere: true });
    },
    refreshRecording: recording.refresh,
  };
}

/**
 * The recording card: start and stop a trial of the session, and what it records (or recorded last).
 * @param {number} sessionId
 */
function recordingCard(sessionId) {
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
    rec.trial = await api.recording(sessionId, { action: "start", name });
    rec.recording = true;
    recName.value = "";
  }).then(renderRecording));
  recStop.addEventListener("click", () => runAction(recStop, recError, async () => {
    rec.trial = await api.recording(sessionId, { action: "stop" });
    rec.recording = false;
  }).then(renderRecording));
  async function refreshRecording() {
    try {
      const trials = await api.listTrials({ session_id: sessionId });
      const active = trials.find((t) => t.status === "recording");
      rec.trial = active || (trials.length ? trials.reduce((a, b) => (b.id > a.id ? b : a)) : null);
      rec.recording = !!active;
      renderRecording();
    } catch (err) {
      showError(recError, err);
    }
  }
  const el = h("section", { class: "card", "data-testid": "recording-card" }, h("h2", { text: "Recording" }),
    recName, h("div", { class: "buttons" }, recStart, recStop), recStatus, recError);
  fence(el, "run");
  /** `state`: the trial, whether it records, whether the session runs (set by the session card). */
  return { el, state: rec, render: renderRecording, refresh: refreshRecording };
}

/**
 * The annotation form: a note on the session's timeline, now.
 * @param {number} sessionId
 * @param {(ev: object) => void} onEvent the annotation's event, once the server has it
 */
function annotationCard(sessionId, onEvent) {
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
      const event = await api.annotate(sessionId, { text });
      annText.value = "";
      onEvent(event);
    });
  });
  fence(annForm, "annotate");
  return annForm;
}
