// The subject page's comparison card: a walk of the subject re-run through the average thigh model and the
// personalized one with a version's fingerprint, overlaid (seed 004, docs/dashboard.md), with the version's fit
// figures and both models' thigh-angle error on that walk. subject.js gives it the versions and the walks, and asks
// it to compare a version (a row's button). By default the walk is held out: the newest walk of the subject the
// version was not fitted on (a calibration fits on every usable stride of its walk, so no part of that walk is
// held out); the walk it was fitted on is marked, and said to be in-sample when it is compared.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { fingerprintEstimators } from "./estimators.js";
import { gText } from "./fingerprint_plot.js";
import { COLORS, Plot } from "./plots.js";
import { errorBox, field, fmt, h, runAction, showError, ValidationError } from "./ui.js";

/** The average and the personalized thigh-model filters (seed 004), by their descriptors' fingerprint variants. */
const [AVERAGE, PERSONAL] = [fingerprintEstimators("average")[0], fingerprintEstimators("personal")[0]];

const RERUN_POINTS = 2000;

/** RMS of `a - b` over the rows both have (null: none). */
function rmse(a, b) {
  let sum = 0;
  let n = 0;
  for (let i = 0; i < Math.min(a.length, b.length); i++) {
    if (a[i] == null || b[i] == null) continue;
    sum += (a[i] - b[i]) ** 2;
    n += 1;
  }
  return n ? Math.sqrt(sum / n) : null;
}

/** Which walk is compared, in words: held out (and which walk it was fitted on) or in-sample, said plainly. */
function sampleText(v, tid, heldOutExists) {
  const fitted = v.source_trial_id ? `fitted on trial ${v.source_trial_id}` : "imported: fitted on another gaitscope's walk";
  if (tid !== v.source_trial_id) return `Held-out walk: trial ${tid}, not used to fit v${v.version} (${fitted}).`;
  return `In-sample: trial ${tid} is the walk v${v.version} was fitted on, so the personalized model looks better here `
    + `than it will on other walks.${heldOutExists ? "" : " No other walk of this subject to hold out yet: record one."}`;
}

/** The comparison charts: each model's output (phase in % of the cycle), the measured thigh angle under its predictions. */
const COMPARE = [
  { key: "phase", title: "Phase: average and personalized model", yLabel: "% of cycle", yRange: [0, 100], out: "phase", scale: 100 },
  { key: "stride", title: "Stride length", yLabel: "m", out: "stride_length_m" },
  { key: "thigh", title: "Thigh angle: measured and each model's prediction", yLabel: "deg", out: "thigh_pred_deg", measured: "thigh_angle_deg" },
];

/**
 * @param {number} subjectId
 * @param {{alive: () => boolean}} hooks `alive` is false once the page is left
 */
export function compareCard(subjectId, hooks) {
  /** @type {Array<any> | null} the subject's versions, once loaded */
  let versions = null;
  let comparing = false;
  /** @type {Array<any>} the subject's usable walks, newest first */
  let walks = [];
  /** @type {Plot[] | null} */
  let plots = null;
  const cmpVersion = h("select", { id: "compare-version", "data-testid": "compare-version" });
  const cmpTrial = h("select", { id: "compare-trial", "data-testid": "compare-trial" });
  const cmpBtn = h("button", { type: "button", class: "primary", "data-testid": "compare-submit", text: "Compare with the average model" });
  const cmpError = errorBox("compare-error");
  const cmpOk = h("p", { class: "ok", role: "status", "data-testid": "compare-ok" });
  const cmpSample = h("p", { "data-testid": "compare-sample", hidden: true });
  const cmpFigures = h("dl", { class: "figures", "data-testid": "compare-figures", hidden: true });
  const cmpPlots = h("div", { class: "compare-plots", hidden: true },
    ...COMPARE.map((c) => h("div", { class: "plot", "data-testid": `compare-plot-${c.key}` })));
  const cmpCard = h("section", { class: "card", "data-testid": "compare-card" }, h("h2", { text: "Compare: average and personalized model" }),
    h("p", { class: "hint", text: "The walk's sensor frames re-run through the average thigh model (fp_avg) and the personalized one "
      + "(fp_ls) with the version's fingerprint, overlaid. Nothing changes for the subject until a version is promoted." }),
    h("div", { class: "compare-controls" }, field("Version", cmpVersion), field("Walk to re-run", cmpTrial), cmpBtn),
    cmpError, cmpSample, cmpOk, cmpFigures, cmpPlots);
  fence(cmpCard, "run"); // a comparison re-runs the walk

  function draw(v, res) {
    cmpPlots.hidden = false;
    const personal = `personalized v${v.version}`;
    const specs = COMPARE.map((c) => ({ ...c, series: [
      ...(c.measured ? [{ label: "measured", color: "#111827", width: 1.5 }] : []),
      { label: "average model", color: COLORS.orange, dash: [6, 4], width: 2 },
      { label: personal, color: COLORS.blue, width: 2.5 },
    ] }));
    if (!plots) plots = specs.map((s, i) => new Plot(cmpPlots.children[i], { ...s, height: 200 }));
    const scale = (a, k) => (k ? a.map((x) => (x == null ? null : x * k)) : a);
    const col = (c) => res[c] || res.t.map(() => null); // a column the re-run lacks: drawn as a gap
    specs.forEach((s, i) => {
      plots[i].setSeries(s.series);
      plots[i].setData([res.t, ...(s.measured ? [col(s.measured)] : []), scale(col(`${AVERAGE}.${s.out}`), s.scale), scale(col(`${PERSONAL}.${s.out}`), s.scale)]);
    });
  }

  /** The newest walk `v` was not fitted on (null: none). */
  const heldOut = (v) => walks.find((t) => t.id !== v.source_trial_id) || null;

  /** The walk picker's options, the one the chosen version was fitted on marked in-sample. */
  function markFitted() {
    const v = versions && versions.find((x) => String(x.id) === cmpVersion.value);
    for (const o of cmpTrial.options) {
      if (o.dataset.label === undefined) o.dataset.label = o.textContent || "";
      const fitted = v && o.value !== "" && Number(o.value) === v.source_trial_id;
      o.textContent = fitted ? `${o.dataset.label} (in-sample: v${v.version} was fitted on it)` : o.dataset.label;
    }
  }
  cmpVersion.addEventListener("change", markFitted);

  /**
   * Re-runs walk `trialId` (null: a held-out walk, the newest the version was not fitted on; its calibration walk
   * when there is none) with the average model and `v`'s fingerprint.
   */
  async function compare(v, trialId) {
    if (comparing) return; // one re-run at a time (a row's button while the card's runs)
    comparing = true;
    showError(cmpError, null);
    cmpVersion.value = String(v.id);
    cmpTrial.value = trialId ? String(trialId) : "";
    markFitted();
    cmpSample.hidden = true;
    cmpOk.textContent = "";
    cmpBtn.textContent = "Re-running…";
    cmpCard.setAttribute("aria-busy", "true");
    await runAction(cmpBtn, cmpError, async () => {
      const held = heldOut(v);
      const tid = trialId || (held ? held.id : v.source_trial_id);
      if (!tid) throw new ValidationError(`v${v.version} was imported and the subject has no walk yet: record one to compare on.`);
      const res = await api.rerun(tid, { estimators: [AVERAGE, PERSONAL], personalization_id: v.id },
        { max_points: RERUN_POINTS });
      if (!hooks.alive()) return;
      if (!res.t || !res.t.length) throw new ValidationError(`The re-run of trial ${tid} produced no samples (it holds no sensor frames).`);
      draw(v, res);
      const own = tid === v.source_trial_id;
      cmpSample.textContent = sampleText(v, tid, held !== null);
      cmpSample.className = own ? "note" : "ok"; // in-sample in the warning colour
      cmpSample.dataset.sample = own ? "in-sample" : "held-out";
      cmpSample.hidden = false;
      const measured = res.thigh_angle_deg || [];
      const [errAvg, errPersonal] = [AVERAGE, PERSONAL].map((e) => rmse(res[`${e}.thigh_pred_deg`] || [], measured));
      const gain = v.fit_rmse_avg_deg > 0 ? Math.round(100 * (1 - v.fit_rmse_personal_deg / v.fit_rmse_avg_deg)) : null;
      const row = (dt, dd, testid) => [h("dt", { text: dt }), h("dd", { "data-testid": testid, text: dd })];
      cmpFigures.replaceChildren(
        ...row("Thigh-angle fit RMSE, average model", `${fmt(v.fit_rmse_avg_deg, 2)} deg`, "figure-rmse-avg"),
        ...row(`Thigh-angle fit RMSE, personalized v${v.version}`, `${fmt(v.fit_rmse_personal_deg, 2)} deg${gain === null ? "" : ` (${gain} % lower)`}`,
          "figure-rmse-personal"),
        ...row("Fitted on", v.source_trial_id ? `trial ${v.source_trial_id}: ${v.strides_used} strides, ${fmt(v.seconds_used, 1)} s` : "another gaitscope (imported)",
          "figure-fitted-on"),
        ...row(`Thigh-angle RMSE on trial ${tid} (${own ? "in-sample" : "held out"}), average model`,
          errAvg === null ? "– (no thigh angle)" : `${fmt(errAvg, 2)} deg`, "figure-walk-rmse-avg"),
        ...row(`Thigh-angle RMSE on trial ${tid} (${own ? "in-sample" : "held out"}), personalized v${v.version}`,
          errPersonal === null ? "– (no thigh angle)" : `${fmt(errPersonal, 2)} deg`, "figure-walk-rmse-personal"));
      cmpFigures.hidden = false;
      cmpOk.textContent = `Trial ${tid} re-run with the average model and v${v.version}'s fingerprint ${gText(v.fingerprint)}`
        + `${own ? " (its calibration walk: in-sample)" : " (held out)"}: ${res.t.length} points.`;
    });
    comparing = false;
    cmpBtn.textContent = "Compare with the average model";
    cmpCard.removeAttribute("aria-busy");
    if (versions) cmpBtn.disabled = !versions.length;
  }

  cmpBtn.addEventListener("click", () => {
    const v = versions && versions.find((x) => String(x.id) === cmpVersion.value);
    if (v) compare(v, Number(cmpTrial.value) || null);
  });

  return {
    el: cmpCard,
    compare,
    /** The version picker's choices: the subject's versions (the choice kept when it is still one of them). */
    setVersions(vs) {
      versions = vs;
      const keep = cmpVersion.value;
      cmpVersion.replaceChildren(...(vs.length ? vs.map((v) => h("option", { value: String(v.id),
        text: `v${v.version} (${v.state}${v.source_trial_id ? `, trial ${v.source_trial_id}` : ", imported"})` }))
        : [h("option", { value: "", text: "— no version yet —" })]));
      if (keep && vs.some((v) => String(v.id) === keep)) cmpVersion.value = keep;
      cmpBtn.disabled = comparing || !vs.length;
      markFitted();
    },
    /** Version `id` chosen in the picker. */
    selectVersion(id) {
      cmpVersion.value = String(id);
      markFitted();
    },
    /**
     * The walk picker's choices (the choice kept when it is still one of them).
     * @param {Array<any>} trials
     * @param {() => HTMLElement[]} options one option per trial, in order
     */
    setTrials(trials, options) {
      const keep = cmpTrial.value;
      walks = trials;
      cmpTrial.replaceChildren(h("option", { value: "", text: "a held-out walk (the newest it was not fitted on)" }), ...options());
      cmpTrial.value = trials.some((t) => String(t.id) === keep) ? keep : "";
      markFitted();
    },
    destroy() {
      if (plots) for (const p of plots) p.destroy();
    },
  };
}
