// Subject page (`#/subjects/{id}`): the subject's personalized gait models (seed 004's fingerprints,
// docs/dashboard.md). The versions and which one runs; calibrating a candidate from one of their trials, or
// from a walk recorded now on a running session of theirs; comparing a version with the average model on a
// re-run; promoting and rolling back; export and import; and where the subject sits among the training
// subjects (fingerprint_plot.js), with the live online fingerprint (`fp_gf`) of a running session of theirs. The
// "record a calibration walk now" flow is people_calibration_walk.js.

import { ApiError, errorText } from "./api.js";
import * as api from "./api_client.js";
import { limitsCard } from "./assistance_limits.js";
import { currentUser, fence, may, refusalReason } from "./auth.js";
import { fingerprintEstimators } from "./estimators.js";
import { fingerprintScatter, gText } from "./fingerprint_plot.js";
import { calibrationWalk } from "./people_calibration_walk.js";
import { LiveFingerprint } from "./subject_live.js";
import { COLORS, Plot } from "./plots.js";
import { errorBox, field, fmt, fmtUtc, h, runAction, showError, ValidationError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

/** The average and the personalized thigh-model filters (seed 004), by their descriptors' fingerprint variants. */
const [AVERAGE, PERSONAL] = [fingerprintEstimators("average")[0], fingerprintEstimators("personal")[0]];

// CalibrationRequest.note and PersonalizationChange.reason (sessions/schema.py), from the generated wire.js.
const TEXT_MAX = FIELD_LIMITS.CalibrationRequest.note.maxLength;
const REASON_MAX = FIELD_LIMITS.PersonalizationChange.reason.maxLength;
const POLL_MS = 5000; // sessions, trials and versions refreshed (another screen may record or promote)
const RERUN_POINTS = 2000;
const COLUMNS = ["Version", "State", "Calibration walk", "Fit RMSE (deg) average → personal", "Fingerprint (deg)", "Created, promoted", "Actions"];
const USABLE = (t) => t.status !== "recording" && t.status !== "damaged";

/** The comparison charts: each model's output (phase in % of the cycle), the measured thigh angle under its predictions. */
const COMPARE = [
  { key: "phase", title: "Phase: average and personalized model", yLabel: "% of cycle", yRange: [0, 100], out: "phase", scale: 100 },
  { key: "stride", title: "Stride length", yLabel: "m", out: "stride_length_m" },
  { key: "thigh", title: "Thigh angle: measured and each model's prediction", yLabel: "deg", out: "thigh_pred_deg", measured: "thigh_angle_deg" },
];

const trialLabel = (t) => `Trial ${t.id}${t.name ? ` · ${t.name}` : ""} · ${fmt(t.duration_s, 1)} s · ${fmtUtc(t.started_utc)}`;
const excludedText = (v) => Object.entries(v.excluded).map(([why, n]) => `${n} ${why}`).join("; ");
const rmseText = (v) => `${fmt(v.fit_rmse_avg_deg, 2)} → ${fmt(v.fit_rmse_personal_deg, 2)}`;

export function mountSubject(root, subjectId) {
  const st = { subject: null, fps: null, fpsSig: null, sessions: [], trialsBySession: new Map(), trials: [], trialsSig: null,
    pending: null, plots: null, fitting: false, walking: false, comparing: false,
    alive: true };
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

  // --- versions -------------------------------------------------------------------------------------
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

  // --- where the subject sits -----------------------------------------------------------------------
  const scatterBox = h("div", { class: "fp-scatter" });
  // not a live region: it changes five times a second (the plot's label says where the dot is)
  const liveText = h("p", { class: "hint", "data-testid": "fp-live-text" });
  const sitsCard = h("section", { class: "card", "data-testid": "sits-card" }, h("h2", { text: "Where the subject sits" }), scatterBox,
    h("ul", { class: "fp-legend", "aria-hidden": "true" }, h("li", {}, h("span", { class: "dot dot-cohort" }), "training subjects"),
      h("li", {}, h("span", { class: "dot dot-version" }), "this subject's versions (active ringed)"),
      h("li", {}, h("span", { class: "dot dot-live" }), "live online fingerprint")), liveText);

  // --- compare --------------------------------------------------------------------------------------
  const cmpVersion = h("select", { id: "compare-version", "data-testid": "compare-version" });
  const cmpTrial = h("select", { id: "compare-trial", "data-testid": "compare-trial" });
  const cmpBtn = h("button", { type: "button", class: "primary", "data-testid": "compare-submit", text: "Compare with the average model" });
  const cmpError = errorBox("compare-error");
  const cmpOk = h("p", { class: "ok", role: "status", "data-testid": "compare-ok" });
  const cmpFigures = h("dl", { class: "figures", "data-testid": "compare-figures", hidden: true });
  const cmpPlots = h("div", { class: "compare-plots", hidden: true },
    ...COMPARE.map((c) => h("div", { class: "plot", "data-testid": `compare-plot-${c.key}` })));
  const cmpCard = h("section", { class: "card", "data-testid": "compare-card" }, h("h2", { text: "Compare: average and personalized model" }),
    h("p", { class: "hint", text: "The walk's sensor frames re-run through the average thigh model (fp_avg) and the personalized one "
      + "(fp_ls) with the version's fingerprint, overlaid. Nothing changes for the subject until a version is promoted." }),
    h("div", { class: "compare-controls" }, field("Version", cmpVersion), field("Walk to re-run", cmpTrial), cmpBtn),
    cmpError, cmpOk, cmpFigures, cmpPlots);
  fence(cmpCard, "run"); // a comparison re-runs the walk

  root.append(h("div", { class: "page subject-page" },
    h("div", { class: "page-head" }, title,
      h("a", { class: "button", href: "#/subjects", "data-testid": "back-to-subjects", text: "← All subjects" }),
      h("a", { class: "button", href: "#/", text: "← Sessions" })),
    body, pageError, modelsCard, limitsCard(subjectId), h("div", { class: "subject-grid" }, calCard, sitsCard), cmpCard));

  // --- rendering --------------------------------------------------------------------------------------
  /** One version's row; every cell names its column (`data-label`), which a narrow screen shows as a caption. */
  function versionRow(v) {
    const cell = (i, props, ...children) => h(i ? "td" : "th", { ...(i ? {} : { scope: "row" }), "data-label": COLUMNS[i], ...props }, ...children);
    const compareBtn = h("button", { type: "button", "data-testid": "compare", text: "Compare" });
    compareBtn.addEventListener("click", () => {
      cmpCard.scrollIntoView({ block: "start" });
      compare(v, null);
    });
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

  function renderModels() {
    const fps = st.fps;
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
    syncCalibrate();
    versionsBody.replaceChildren(...(fps.versions.length ? fps.versions.map(versionRow)
      : [h("tr", {}, h("td", { colspan: COLUMNS.length, class: "empty", text: "No personalized model yet: calibrate one from a walk below." }))]));
    const keep = cmpVersion.value;
    cmpVersion.replaceChildren(...(fps.versions.length ? fps.versions.map((v) => h("option", { value: String(v.id),
      text: `v${v.version} (${v.state}${v.source_trial_id ? `, trial ${v.source_trial_id}` : ", imported"})` }))
      : [h("option", { value: "", text: "— no version yet —" })]));
    if (keep && fps.versions.some((v) => String(v.id) === keep)) cmpVersion.value = keep;
    cmpBtn.disabled = st.comparing || !fps.versions.length;
  }

  function renderScatter() {
    const fps = st.fps;
    if (!fps) return;
    if (!fps.components) {
      scatterBox.replaceChildren(h("p", { class: "hint", text: "The model has no fingerprint map: there is nothing to place the subject in." }));
      return;
    }
    scatterBox.replaceChildren(fingerprintScatter(fps, code(), live.live));
  }

  function renderLive() {
    liveText.textContent = live.text();
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
    const keepCmp = cmpTrial.value;
    cmpTrial.replaceChildren(h("option", { value: "", text: "the version's calibration walk" }), ...options());
    cmpTrial.value = st.trials.some((t) => String(t.id) === keepCmp) ? keepCmp : "";
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
      cmpVersion.value = String(p.id);
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

  // --- compare ----------------------------------------------------------------------------------------------
  function drawCompare(v, res) {
    cmpPlots.hidden = false;
    const personal = `personalized v${v.version}`;
    const specs = COMPARE.map((c) => ({ ...c, series: [
      ...(c.measured ? [{ label: "measured", color: "#111827", width: 1.5 }] : []),
      { label: "average model", color: COLORS.orange, dash: [6, 4], width: 2 },
      { label: personal, color: COLORS.blue, width: 2.5 },
    ] }));
    if (!st.plots) st.plots = specs.map((s, i) => new Plot(cmpPlots.children[i], { ...s, height: 200 }));
    const scale = (a, k) => (k ? a.map((x) => (x == null ? null : x * k)) : a);
    const col = (c) => res[c] || res.t.map(() => null); // a column the re-run lacks: drawn as a gap
    specs.forEach((s, i) => {
      st.plots[i].setSeries(s.series);
      st.plots[i].setData([res.t, ...(s.measured ? [col(s.measured)] : []), scale(col(`${AVERAGE}.${s.out}`), s.scale), scale(col(`${PERSONAL}.${s.out}`), s.scale)]);
    });
  }

  async function compare(v, trialId) {
    if (st.comparing) return; // one re-run at a time (a row's button while the card's runs)
    st.comparing = true;
    showError(cmpError, null);
    cmpVersion.value = String(v.id);
    cmpTrial.value = trialId ? String(trialId) : "";
    cmpOk.textContent = "";
    cmpBtn.textContent = "Re-running…";
    cmpCard.setAttribute("aria-busy", "true");
    await runAction(cmpBtn, cmpError, async () => {
      const tid = trialId || v.source_trial_id;
      if (!tid) throw new ValidationError(`v${v.version} was imported: it has no calibration walk here. Choose a walk to re-run.`);
      const res = await api.rerun(tid, { estimators: [AVERAGE, PERSONAL], personalization_id: v.id },
        { max_points: RERUN_POINTS });
      if (!st.alive) return;
      if (!res.t || !res.t.length) throw new ValidationError(`The re-run of trial ${tid} produced no samples (it holds no sensor frames).`);
      drawCompare(v, res);
      const own = tid === v.source_trial_id;
      const gain = v.fit_rmse_avg_deg > 0 ? Math.round(100 * (1 - v.fit_rmse_personal_deg / v.fit_rmse_avg_deg)) : null;
      const row = (dt, dd, testid) => [h("dt", { text: dt }), h("dd", { "data-testid": testid, text: dd })];
      cmpFigures.replaceChildren(
        ...row("Thigh-angle fit RMSE, average model", `${fmt(v.fit_rmse_avg_deg, 2)} deg`, "figure-rmse-avg"),
        ...row(`Thigh-angle fit RMSE, personalized v${v.version}`, `${fmt(v.fit_rmse_personal_deg, 2)} deg${gain === null ? "" : ` (${gain} % lower)`}`,
          "figure-rmse-personal"),
        ...row("Fitted on", v.source_trial_id ? `trial ${v.source_trial_id}: ${v.strides_used} strides, ${fmt(v.seconds_used, 1)} s` : "another gaitscope (imported)",
          "figure-fitted-on"));
      cmpFigures.hidden = false;
      cmpOk.textContent = `Trial ${tid} re-run with the average model and v${v.version}'s fingerprint ${gText(v.fingerprint)}`
        + `${own ? " (its calibration walk)" : ""}: ${res.t.length} points.`;
    });
    st.comparing = false;
    cmpBtn.textContent = "Compare with the average model";
    cmpCard.removeAttribute("aria-busy");
    if (st.fps) cmpBtn.disabled = !st.fps.versions.length;
  }

  cmpBtn.addEventListener("click", () => {
    const v = st.fps && st.fps.versions.find((x) => String(x.id) === cmpVersion.value);
    if (v) compare(v, Number(cmpTrial.value) || null);
  });

  // --- promote, roll back ------------------------------------------------------------------------------------
  function ask(what) {
    st.pending = what;
    showError(changeError, null);
    status.textContent = "";
    const sessions = `Running sessions of ${code()} log it; a session running the personalized filter (fp_ls) takes it at its next heel strike.`;
    if (what.kind === "promote") {
      const v = what.v;
      confirmText.textContent = `Promote v${v.version} (${v.state}, fit RMSE ${rmseText(v)} deg) as ${code()}'s model? ${sessions}`;
      confirmBtn.textContent = `Promote v${v.version}`;
    } else {
      const a = st.fps.active;
      confirmText.textContent = `Roll back v${a.version}? ${code()} goes back to the version it replaced, or to the average model if it replaced none. ${sessions}`;
      confirmBtn.textContent = `Roll back v${a.version}`;
    }
    confirmBox.hidden = false;
    confirmBtn.focus();
  }

  function closeConfirm() {
    st.pending = null;
    confirmBox.hidden = true;
    reason.value = "";
  }

  rollbackBtn.addEventListener("click", () => {
    if (st.fps && st.fps.active) ask({ kind: "rollback" });
  });
  cancelBtn.addEventListener("click", () => {
    closeConfirm();
    showError(changeError, null);
  });
  confirmBtn.addEventListener("click", () => {
    const what = st.pending;
    if (!what) return;
    const why = reason.value.trim();
    const said = why ? ` (${why})` : "";
    runAction(confirmBtn, changeError, async () => {
      const body = { reason: why };
      if (what.kind === "promote") {
        const p = await api.promoteFingerprint(subjectId, what.v.id, body);
        status.textContent = `v${p.version} promoted by ${p.promoted_by}${said}: it is ${code()}'s model now.`;
      } else {
        const old = st.fps.active;
        if (!old) throw new ValidationError("Nothing to roll back: no personalized model is active (changed on another screen?).");
        const fps = await api.rollbackFingerprint(subjectId, body, { model: st.fps.model });
        status.textContent = `v${old.version} rolled back by ${currentUser().name}${said}: `
          + `${fps.active ? `v${fps.active.version} is in use again` : "the average model is in use again"}.`;
      }
      closeConfirm();
      await loadModels();
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
    await loadModels();
  }));

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
      if (st.plots) for (const p of st.plots) p.destroy();
    },
  };
}
