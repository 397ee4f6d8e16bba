// A subject's speed-change intent model (seed 001; issue #26): which variant their intent filter runs (uninjured,
// or iSCI with the hip-motor current model) and its step-length model, the cohort's by default or fitted on one of
// their walks (`GET/PUT/DELETE /api/subjects/{id}/intent-model`, IntentModel). Everyone sees it on the subject page;
// clinicians and admins set it. It runs from the subject's next session on: a running session keeps its own.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { errorBox, field, fmt, fmtUtc, h, runAction, showError } from "./ui.js";

const VARIANTS = { uninjured: "Uninjured (step length)", isci: "Incomplete SCI (step length and hip-motor current)" };

/** "kappa 0.242, 0.356, 0.419; alpha 8.61, 4.24" for a model. */
export function modelText(m) {
  const kappa = `kappa ${m.kappa.map((x) => fmt(x, 3)).join(", ")}`;
  return m.alpha ? `${kappa}; alpha ${m.alpha.map((x) => fmt(x, 2)).join(", ")}` : kappa;
}

/**
 * The subject page's card; `setTrials(trials, options)` fills its walk select as the page's other selects.
 * @param {number} subjectId
 */
export function intentModelCard(subjectId) {
  const summary = h("p", { "data-testid": "intent-model-summary", text: "Loading…" });
  const source = h("p", { class: "hint", "data-testid": "intent-model-source" });
  const variant = h("select", { id: "intent-model-variant", "data-testid": "intent-model-variant" },
    ...Object.entries(VARIANTS).map(([v, text]) => h("option", { value: v, text })));
  const trial = h("select", { id: "intent-model-trial", "data-testid": "intent-model-trial" });
  const save = h("button", { type: "button", class: "primary", "data-testid": "intent-model-save", text: "Set the model" });
  const reset = h("button", { type: "button", "data-testid": "intent-model-reset", text: "Back to the default" });
  const error = errorBox("intent-model-error");
  const ok = h("p", { class: "ok", role: "status", "data-testid": "intent-model-ok" });
  const form = h("div", { class: "limits-form" },
    h("div", { class: "limits-fields" }, field("Variant", variant),
      field("Fit on a walk", trial, "a walk with speed changes; none: the variant's default")),
    h("div", { class: "buttons" }, save, reset), error, ok);
  const card = h("section", { class: "card", "data-testid": "intent-model-card" }, h("h2", { text: "Speed-change intent model" }),
    h("p", { class: "hint", text: "What the intent filter (seed 001) reads a step's length against. It runs from the subject's next session on." }),
    summary, source, fence(form, "promote", "Only a clinician or an admin sets the intent model."));

  function show(m) {
    summary.textContent = `${VARIANTS[m.variant]}: ${modelText(m)}.`;
    const fit = m.steps ? ` on ${m.steps} steps, step length RMSE ${fmt(100 * m.step_rmse_m, 1)} cm` : "";
    const by = m.updated_utc ? ` Set by ${m.actor} on ${fmtUtc(m.updated_utc)}.` : "";
    source.textContent = `${m.source[0].toUpperCase()}${m.source.slice(1)}${fit}.${by}`;
    variant.value = m.variant;
  }
  save.addEventListener("click", () => {
    ok.textContent = "";
    runAction(save, error, async () => {
      const body = { variant: variant.value, trial_id: trial.value ? Number(trial.value) : null };
      show(await api.setIntentModel(subjectId, body));
      ok.textContent = "Saved: the subject's next session runs it.";
    });
  });
  reset.addEventListener("click", () => {
    ok.textContent = "";
    runAction(reset, error, async () => {
      show(await api.resetIntentModel(subjectId));
      ok.textContent = "Back to the default from the next session.";
    });
  });
  api.getIntentModel(subjectId).then(show, (err) => {
    summary.textContent = "";
    showError(error, err);
  });
  function setTrials(trials, options) {
    const keep = trial.value;
    trial.replaceChildren(h("option", { value: "", text: "— none: the variant's default —" }), ...options());
    trial.value = trials.some((t) => String(t.id) === keep) ? keep : "";
  }
  return { el: card, setTrials };
}
