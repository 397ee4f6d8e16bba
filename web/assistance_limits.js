// The experimenters' assistance limits of a subject (issue #13): the most torque gain, maximum torque and intent
// boost an experimenter may set for them (`GET/PUT /api/subjects/{id}/assistance-limits`, AssistanceLimits).
// Clinicians and admins set them on the subject page; everyone sees them there. On the live page an experimenter
// sees them next to the assistance settings, and a change beyond them is refused before it is sent, with the
// reason; the server checks again and its 403 is shown as it says it.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { SETTING_LIMITS } from "./settings.js";
import { errorBox, field, fmt, fmtUtc, h, readNumber, runAction, showError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

/** The limited settings, in the server's order (server/routes/common.py's LIMITED_SETTINGS). */
export const LIMITED = Object.keys(FIELD_LIMITS.AssistanceLimits);
const label = (k) => SETTING_LIMITS[k].label.split(":")[0];
const unit = (k) => (SETTING_LIMITS[k].unit === "×" ? "" : ` ${SETTING_LIMITS[k].unit}`);

/** "torque gain at most 1.20, maximum torque at most 20.0 N·m, …" (null: none set). */
export function limitsText(limits) {
  if (!limits) return "none set: experimenters may not change assistance for this subject until a clinician sets them";
  return LIMITED.map((k) => `${label(k).toLowerCase()} at most ${fmt(limits[k], SETTING_LIMITS[k].digits)}${unit(k)}`).join(", ");
}

/**
 * What an experimenter may not send: the reason (a sentence) or null when `changes` are within `limits`.
 * Lowering is always allowed; with no limits set, no assistance change is.
 * @param {object} changes setting -> new value (only the changed ones)
 * @param {object|null} limits the subject's SubjectLimits, or null
 */
export function overLimits(changes, limits) {
  const asked = LIMITED.filter((k) => changes[k] !== undefined && changes[k] !== null);
  if (!asked.length) return null;
  if (!limits) return "No assistance limits are set for this subject: a clinician sets them before an experimenter may change assistance.";
  const over = asked.filter((k) => changes[k] > limits[k]);
  if (!over.length) return null;
  return `Over the clinician's limits for this subject: ${over.map((k) =>
    `${label(k).toLowerCase()} ${fmt(changes[k], SETTING_LIMITS[k].digits)} is above ${fmt(limits[k], SETTING_LIMITS[k].digits)}${unit(k)}`).join("; ")}. Ask a clinician.`;
}

/** `GET` the subject's limits (null: none set). */
export function loadLimits(subjectId) {
  return api.assistanceLimits(subjectId);
}

/** The subject page's card: the limits for all to see; a form for those who may set them. */
export function limitsCard(subjectId) {
  const summary = h("p", { "data-testid": "limits-summary", text: "Loading…" });
  const who = h("p", { class: "hint", "data-testid": "limits-set-by" });
  const inputs = Object.fromEntries(LIMITED.map((k) => {
    const lim = FIELD_LIMITS.AssistanceLimits[k];
    return [k, h("input", { id: `limits-${k}`, "data-testid": `limits-${k}`, type: "number", inputmode: "decimal",
      min: lim.min, max: lim.max, step: SETTING_LIMITS[k].step })];
  }));
  const save = h("button", { type: "button", class: "primary", "data-testid": "limits-save", text: "Save limits" });
  const error = errorBox("limits-error");
  const ok = h("p", { class: "ok", role: "status", "data-testid": "limits-ok" });
  const form = h("div", { class: "limits-form" },
    h("div", { class: "limits-fields" }, ...LIMITED.map((k) => field(`${label(k)}${unit(k) ? ` (${unit(k).trim()})` : ""}`, inputs[k],
      `${FIELD_LIMITS.AssistanceLimits[k].min} to ${FIELD_LIMITS.AssistanceLimits[k].max}`))),
    h("div", { class: "buttons" }, save), error, ok);
  const card = h("section", { class: "card", "data-testid": "limits-card" }, h("h2", { text: "Assistance limits for experimenters" }),
    h("p", { class: "hint", text: "The most an experimenter may set for this subject. Clinicians and admins are not bound by them." }),
    summary, who, fence(form, "set_limits", "Only a clinician or an admin sets these limits."));

  function show(limits) {
    summary.textContent = `Limits: ${limitsText(limits)}.`;
    who.textContent = limits ? `Set by ${limits.set_by} on ${fmtUtc(limits.set_utc)}.` : "";
    for (const k of LIMITED) inputs[k].value = limits ? String(limits[k]) : "";
  }
  save.addEventListener("click", () => {
    ok.textContent = "";
    runAction(save, error, async () => {
      const body = {};
      for (const k of LIMITED) {
        const lim = FIELD_LIMITS.AssistanceLimits[k];
        body[k] = readNumber(inputs[k], { label: label(k), min: lim.min, max: lim.max });
      }
      const saved = await api.setAssistanceLimits(subjectId, body);
      show(saved);
      ok.textContent = "Saved: experimenters are held to these limits from their next change.";
    });
  });
  loadLimits(subjectId).then(show, (err) => {
    summary.textContent = "";
    showError(error, err);
  });
  return card;
}
