// The subject page's models card: the versions of the subject's personalized gait model (seed 004's
// fingerprints) and which one runs; promoting and rolling back (a confirm step with an optional reason);
// export (a link per version) and import. subject.js loads the versions and draws them through `render`.

import * as api from "./api_client.js";
import { currentUser, fence, may, refusalReason } from "./auth.js";
import { estimatorLabel, fingerprintEstimators } from "./estimators.js";
import { gText } from "./fingerprint_plot.js";
import { errorBox, field, fmt, fmtUtc, h, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

// PersonalizationChange.reason (sessions/schema.py), from the generated wire.js.
const REASON_MAX = FIELD_LIMITS.PersonalizationChange.reason.maxLength;
/** The fingerprint filter that runs the subject's active personalization (its descriptor's role). */
const PERSONAL = fingerprintEstimators("personal")[0];
const COLUMNS = ["Version", "State", "Calibration walk", "Fit RMSE (deg) average → personal", "Fingerprint (deg)", "Created, promoted", "Actions"];

/** What a fit left out, e.g. "2 too short; 1 not steady". */
export const excludedText = (v) => Object.entries(v.excluded).map(([why, n]) => `${n} ${why}`).join("; ");
/** A version's fit RMSE, average model → personalized. */
export const rmseText = (v) => `${fmt(v.fit_rmse_avg_deg, 2)} → ${fmt(v.fit_rmse_personal_deg, 2)}`;

/**
 * @param {number} subjectId
 * @param {{code: () => string, fps: () => (Record<string, any> | null), reload: () => Promise<void>,
 *   compare: (v: Record<string, any>) => void}} hooks `code` names the subject, `fps` is the versions loaded,
 *   `reload` loads them again after a change, `compare` is a row's Compare button.
 */
export function modelsCard(subjectId, hooks) {
  /** @type {{kind: "promote", v: Record<string, any>} | {kind: "rollback"} | null} the change being confirmed */
  let pending = null;
  const { code } = hooks;
  const modelNote = h("p", { class: "hint", "data-testid": "model-note" });
  const activeLine = h("p", { class: "active-model", "data-testid": "active-model", role: "status" });
  const status = h("p", { class: "ok", role: "status", "data-testid": "models-status" });
  const rollbackBtn = h("button", { type: "button", class: "danger", "data-testid": "rollback", text: "Roll back…", disabled: true });
  const versionsBody = h("tbody", {});
  const versionsTable = h("table", { class: "table versions", "data-testid": "versions-table" },
    h("thead", {}, h("tr", {}, ...COLUMNS.map((t) => h("th", { scope: "col", text: t })))),
    versionsBody);
  // the confirm step of a promotion or a roll back, with its optional reason
  const confirmText = h("p", { id: "confirm-text", class: "confirm-text", "data-testid": "confirm-text" });
  const reason = h("input", { id: "change-reason", "data-testid": "change-reason", maxlength: REASON_MAX, autocomplete: "off",
    placeholder: "e.g. tracks her thigh better on the 6-minute walk" });
  const confirmBtn = h("button", { type: "button", class: "primary", "data-testid": "confirm-apply" });
  const cancelBtn = h("button", { type: "button", "data-testid": "confirm-cancel", text: "Cancel" });
  const changeError = errorBox("change-error");
  const confirmBox = h("div", { class: "confirm", role: "group", "aria-labelledby": "confirm-text", "data-testid": "confirm", hidden: true },
    confirmText, field("Reason (optional, kept in the sessions' event logs)", reason), h("div", { class: "buttons" }, confirmBtn, cancelBtn));
  // import (export is a link per version)
  const importFile = h("input", { type: "file", id: "import-file", "data-testid": "import-file", accept: ".json,application/json" });
  const importBtn = h("button", { type: "button", "data-testid": "import-submit", text: "Import as a candidate" });
  const importError = errorBox("import-error");
  const modelsCard = h("section", { class: "card", "data-testid": "models-card" },
    h("div", { class: "card-head" }, h("h2", { text: "Personalized models" }), rollbackBtn),
    modelNote, activeLine, h("div", { class: "table-scroll" }, versionsTable), confirmBox, changeError, status,
    h("details", { class: "import" }, h("summary", { text: "Import a version exported from another gaitscope" }),
      fence(h("div", {}, h("div", { class: "inline" }, field("Personalization file (.json)", importFile), importBtn), importError), "upload")));

  /** One version's row; every cell names its column (`data-label`), which a narrow screen shows as a caption. */
  function versionRow(v) {
    const cell = (i, props, ...children) => h(i ? "td" : "th", { ...(i ? {} : { scope: "row" }), "data-label": COLUMNS[i], ...props }, ...children);
    const compareBtn = h("button", { type: "button", "data-testid": "compare", text: "Compare" });
    compareBtn.addEventListener("click", () => hooks.compare(v));
    return h("tr", { class: v.state === "active" ? "is-active" : null, "data-testid": "version-row", "data-version": v.version, "data-state": v.state },
      cell(0, {}, `v${v.version}`, v.note ? h("div", { class: "hint", text: v.note }) : null),
      cell(1, {}, h("span", { class: `badge badge-${v.state}`, "data-testid": "version-state", text: v.state === "active" ? "ACTIVE" : v.state })),
      cell(2, {}, v.source_trial_id === null ? "imported" : h("a", { href: `#/trials/${v.source_trial_id}`, text: `Trial ${v.source_trial_id}` }),
        h("div", { class: "hint", "data-testid": "version-walk", text: `${v.strides_used} strides used, ${v.strides_excluded} left out`
          + `${v.strides_excluded ? ` (${excludedText(v)})` : ""}; ${fmt(v.seconds_used, 1)} s; stride length: ${v.stride_length_source}` })),
      cell(3, { class: "num", "data-testid": "version-rmse", text: rmseText(v) }),
      cell(4, { class: "fingerprint", "data-testid": "version-fingerprint", text: gText(v.fingerprint) }),
      cell(5, {}, fmtUtc(v.created_utc), h("div", { class: "hint", text: `by ${v.created_by}` }),
        v.promoted_utc ? h("div", { class: "hint", text: `promoted ${fmtUtc(v.promoted_utc)} by ${v.promoted_by}` }) : null),
      cell(6, {}, h("div", { class: "row-actions" }, compareBtn,
        v.state === "active" ? null : h("button", { type: "button", "data-testid": "promote", text: "Promote…", onclick: () => ask({ kind: "promote", v }),
          disabled: !may("promote"), title: may("promote") ? null : refusalReason("promote") }),
        h("a", { class: "button", "data-testid": "export", href: api.exportFingerprintUrl(subjectId, v.id), download: `${code()}-fingerprint-v${v.version}.json`,
          text: "Export" }))));
  }

  /** The model, the active version and the versions' table, from `fps` (the subject's fingerprints). */
  function render(fps) {
    const a = fps.active;
    const share = (i) => fmt(100 * fps.explained[i], 0);
    modelNote.textContent = fps.components
      ? `Model “${fps.model}”: fingerprints of ${fps.components} numbers (g1 tells ${share(0)} % of how the training subjects' `
        + `thigh patterns differ${fps.components > 1 ? `, g1 and g2 ${share(1)} %` : ""}).`
      : `Model “${fps.model}” has no fingerprint map (it was trained without thigh angles): it cannot be personalized.`;
    activeLine.replaceChildren(a
      ? h("span", {}, h("span", { class: "badge badge-active", text: "ACTIVE" }), ` v${a.version} is in use, promoted by ${a.promoted_by} `
        + `on ${fmtUtc(a.promoted_utc)}: ${gText(a.fingerprint)}.`)
      : h("span", {}, h("span", { class: "badge badge-average", text: "AVERAGE MODEL" }),
        " No personalized model is active: the average model is in use."));
    rollbackBtn.disabled = !a || !may("promote");
    rollbackBtn.title = may("promote") ? "" : refusalReason("promote");
    versionsBody.replaceChildren(...(fps.versions.length ? fps.versions.map(versionRow)
      : [h("tr", {}, h("td", { colspan: COLUMNS.length, class: "empty", text: "No personalized model yet: calibrate one from a walk below." }))]));
  }

  // --- promote, roll back ------------------------------------------------------------------------------------
  function ask(what) {
    pending = what;
    showError(changeError, null);
    status.textContent = "";
    // the server asks the same (confirm) while a running session's torque follows the personalized filter
    const sessions = `Running sessions of ${code()} log it; a session running the ${estimatorLabel(PERSONAL)} takes it at its next heel strike, `
      + "and where it drives the torque, the torque changes with it.";
    if (what.kind === "promote") {
      const v = what.v;
      confirmText.textContent = `Promote v${v.version} (${v.state}, fit RMSE ${rmseText(v)} deg) as ${code()}'s model? ${sessions}`;
      confirmBtn.textContent = `Promote v${v.version}`;
    } else {
      const a = hooks.fps().active;
      confirmText.textContent = `Roll back v${a.version}? ${code()} goes back to the version it replaced, or to the average model if it replaced none. ${sessions}`;
      confirmBtn.textContent = `Roll back v${a.version}`;
    }
    confirmBox.hidden = false;
    confirmBtn.focus();
  }

  function closeConfirm() {
    pending = null;
    confirmBox.hidden = true;
    reason.value = "";
  }

  rollbackBtn.addEventListener("click", () => {
    const fps = hooks.fps();
    if (fps && fps.active) ask({ kind: "rollback" });
  });
  cancelBtn.addEventListener("click", () => {
    closeConfirm();
    showError(changeError, null);
  });
  confirmBtn.addEventListener("click", () => {
    const what = pending;
    if (!what) return;
    const why = reason.value.trim();
    const said = why ? ` (${why})` : "";
    runAction(confirmBtn, changeError, async () => {
      const body = { reason: why, confirm: true }; // confirmed: the box above said what it changes
      if (what.kind === "promote") {
        const p = await api.promoteFingerprint(subjectId, what.v.id, body);
        status.textContent = `v${p.version} promoted by ${p.promoted_by}${said}: it is ${code()}'s model now.`;
      } else {
        const old = hooks.fps().active;
        if (!old) throw new ValidationError("Nothing to roll back: no personalized model is active (changed on another screen?).");
        const fps = await api.rollbackFingerprint(subjectId, body, { model: hooks.fps().model });
        status.textContent = `v${old.version} rolled back by ${currentUser().name}${said}: `
          + `${fps.active ? `v${fps.active.version} is in use again` : "the average model is in use again"}.`;
      }
      closeConfirm();
      await hooks.reload();
    });
  });

  // --- import -------------------------------------------------------------------------------------------------
  importBtn.addEventListener("click", () => runAction(importBtn, importError, async () => {
    const f = importFile.files && importFile.files[0];
    if (!f) throw new ValidationError("Choose the exported personalization file (.json).");
    let data;
    try {
      data = JSON.parse(await f.text());
    } catch {
      throw new ValidationError(`${f.name} is not a personalization file (it is not JSON).`);
    }
    const p = await api.importFingerprint(subjectId, data);
    importFile.value = "";
    status.textContent = `Imported as candidate v${p.version} (${gText(p.fingerprint)}). Compare it on a walk of ${code()} before promoting it.`;
    await hooks.reload();
  }));

  return { el: modelsCard, render };
}
