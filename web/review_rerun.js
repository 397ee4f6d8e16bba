// The review's re-run card: the trial's raw frames through the chosen estimators again. Two modes
// (RerunRequest): "recorded" sends no settings, and the server replays the recorded ones and their changes,
// so the overlay lies on the recording; "whatif" holds the editor's settings over the whole trial. Editing a
// setting chooses "what if". The estimators: the trial's recorded stack by default (then no `estimators` is
// sent), any runnable subset. The card asks the server; the review draws the answer (`hooks.show`).

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { EstimatorPicker, estimatorLabel, listText, overlayLegend } from "./estimators.js";
import { changeText, settingLabel } from "./review_markers.js";
import { SETTING_LIMITS, SettingsEditor } from "./settings.js";
import { errorBox, fmt, h, runAction } from "./ui.js";
import { DEFAULT_SETTINGS } from "./wire.js";

export const RERUN_POINTS = 10000; // kept of a re-run, decimated again to MAX_POINTS per view

/**
 * @param {number} trialId
 * @param {{alive: () => boolean, baseSettings: () => (Record<string, any> | null), events: () => Array<any>,
 *   show: (res: Record<string, any>) => {names: string[], drawn: object}, clear: () => void}} hooks
 *   `show` overlays a re-run's answer (throws when it cannot) and says which estimators it drew; `clear` removes it.
 */
export function rerunCard(trialId, hooks) {
  const picker = new EstimatorPicker(() => refresh());
  const editor = new SettingsEditor("rerun");
  // SessionSettings' defaults until the trial's recorded settings are loaded.
  editor.setBaseline(DEFAULT_SETTINGS);
  const modeChoice = (mode, text) => h("label", { class: "choice" },
    h("input", { type: "radio", name: "rerun-mode", value: mode, "data-testid": `rerun-mode-${mode}`, checked: mode === "recorded" }),
    h("span", { text }));
  const modeRecorded = modeChoice("recorded", "Re-run with the recorded settings (default)");
  const modeWhatIf = modeChoice("whatif", "What if: these settings over the whole trial");
  const modeNote = h("p", { class: "hint", "data-testid": "rerun-mode-note" });
  const rerunBtn = h("button", { type: "button", class: "primary", "data-testid": "rerun-submit",
    "aria-describedby": "rerun-estimators-error" });
  const rerunClear = h("button", { type: "button", "data-testid": "rerun-clear", text: "Remove overlay", disabled: true });
  const rerunError = errorBox("rerun-error");
  const rerunOk = h("p", { class: "ok", role: "status", "data-testid": "rerun-ok" });
  // how the re-run's estimators began, and how far its torque is from the recorded one (rerun_series' answer)
  const rerunFidelity = h("p", { class: "hint", "data-testid": "rerun-fidelity", hidden: true });
  const rerunLegend = h("ul", { class: "overlay-legend", "data-testid": "rerun-legend", "aria-label": "Estimators overlaid", hidden: true });
  const rerunStart = h("p", { class: "rerun-start", "data-testid": "rerun-start", text: "A re-run starts from the settings "
    + "that ran: those recorded when the trial began, then each recorded change at the moment it happened (listed below "
    + "and marked on the timeline). Choose \"What if\" to hold other settings over the whole trial instead." });
  const rerunChanges = h("ul", { class: "rerun-changes", "data-testid": "rerun-changes", "aria-label": "Recorded setting changes" });
  const el = h("section", { class: "card", "data-testid": "rerun-card" }, h("h2", { text: "Re-run" }),
    rerunStart, h("h3", { text: "Recorded setting changes" }), rerunChanges,
    h("p", { class: "hint", text: "The trial's raw sensor frames through the chosen estimators again. The re-run's gait state "
      + "(the phase the torque follows, the torque, the incline) is overlaid in purple; each estimator's own outputs in its colour." }),
    picker.el,
    h("fieldset", { class: "choices" }, h("legend", { text: "Settings" }), modeRecorded, modeWhatIf), modeNote,
    editor.el, h("div", { class: "buttons" }, rerunBtn, rerunClear), rerunError, rerunOk, rerunFidelity, rerunLegend);
  fence(el, "run");
  const radio = (label) => label.querySelector("input");
  const whatIf = () => radio(modeWhatIf).checked;
  let rerunning = false;
  // The button says what will be re-run, and how; it is disabled while the choice cannot run (the picker says why).
  function refresh() {
    const problem = picker.problem();
    const what = picker.summary();
    rerunBtn.textContent = problem ? "Re-run: choose the estimators first"
      : whatIf() ? `Re-run ${what}: what if` : `Re-run ${what} with the recorded settings`;
    rerunBtn.title = picker.selected() ? picker.selected().map((n) => `${estimatorLabel(n)} (${n})`).join(", ") : "";
    rerunBtn.disabled = rerunning || problem !== null;
  }
  function showMode() {
    refresh();
    modeNote.textContent = whatIf()
      ? "These settings held from the first frame to the last; the recorded changes are not applied."
      : "The settings in force when the trial began (shown below), and every recorded change where it happened: the re-run reproduces what ran.";
  }
  el.addEventListener("change", (ev) => {
    if (ev.target.name === "rerun-mode") showMode();
  });
  editor.el.addEventListener("input", () => {
    radio(modeWhatIf).checked = true;
    showMode();
  });
  showMode();

  rerunBtn.addEventListener("click", () => {
    if (picker.problem() !== null) return;
    rerunOk.textContent = "";
    rerunning = true;
    runAction(rerunBtn, rerunError, async () => {
      const asWhatIf = whatIf();
      const settings = asWhatIf ? editor.values() : null;
      const estimators = picker.request(); // null: the recorded stack, as recorded
      rerunOk.textContent = "re-running…";
      showFidelity(null);
      // The model and anything the editor does not show come from the recorded settings.
      const body = { ...(asWhatIf ? { settings: { ...hooks.baseSettings(), ...settings } } : {}), ...(estimators ? { estimators } : {}) };
      const res = await api.rerun(trialId, body, { max_points: RERUN_POINTS });
      if (!hooks.alive()) return;
      const { names, drawn } = hooks.show(res);
      overlayLegend(rerunLegend, names, drawn);
      rerunClear.disabled = false;
      const changes = hooks.events().filter((e) => e.kind === "setting").length;
      const ran = `Estimators: ${listText(names.map(estimatorLabel))}.`;
      rerunOk.textContent = asWhatIf
        ? `Overlaid: ${whatIfText(settings)} (what if, over the whole trial). ${ran}`
        : `Overlaid: the recorded settings, ${changes} recorded change${changes === 1 ? "" : "s"} replayed`
          + `${estimators ? "" : " (what ran)"}. ${ran}`;
      showFidelity(res);
    }).then(() => {
      rerunning = false;
      refresh();
      if (rerunOk.textContent === "re-running…") rerunOk.textContent = "";
    });
  });
  /** A what-if's settings in words: those that differ from the ones the trial began with. */
  function whatIfText(settings) {
    const base = hooks.baseSettings() || {};
    const changed = Object.entries(settings).filter(([k, v]) => base[k] === undefined || Math.abs(v - base[k]) > 1e-9);
    if (!changed.length) return "the settings the trial began with, held without its changes";
    return changed.map(([k, v]) => `${settingLabel(k)} ${fmt(v, (SETTING_LIMITS[k] && SETTING_LIMITS[k].digits) || 2)}`).join(", ");
  }
  /** The re-run's largest torque difference from the recording, and how its estimators began (null: none shown). */
  function showFidelity(res) {
    const diff = res && Array.isArray(res.recorded_torque_diff_Nm) ? res.recorded_torque_diff_Nm[0] : null;
    const start = res && Array.isArray(res.start) ? res.start[0] : "";
    rerunFidelity.hidden = res === null || (diff == null && !start);
    if (rerunFidelity.hidden) return rerunFidelity.replaceChildren();
    const figure = diff == null ? "no recorded torque to compare with"
      : diff === 0 ? "0 N·m (identical to what ran)" : `${fmt(diff, 3)} N·m`;
    rerunFidelity.replaceChildren(h("span", { text: "Largest |torque difference| from the recording: " }),
      h("span", { class: "num", "data-testid": "rerun-torque-diff", "data-value": diff == null ? "" : String(diff), text: figure }),
      h("span", { text: `. ${start}` }));
  }
  rerunClear.addEventListener("click", () => {
    rerunClear.disabled = true;
    rerunOk.textContent = "";
    showFidelity(null);
    overlayLegend(rerunLegend, [], {});
    hooks.clear();
  });

  return {
    el,
    picker,
    /** The recorded setting changes in words (what a re-run with them replays). */
    showChanges() {
      const changes = hooks.events().filter((e) => e.kind === "setting");
      rerunChanges.replaceChildren(...(changes.length
        ? changes.map((e) => h("li", { "data-testid": "rerun-change" }, h("span", { class: "num", text: `at ${fmt(e.t, 1)} s: ` }),
          h("span", { text: changeText(e) })))
        : [h("li", { class: "hint", text: "None: the settings stayed as they began." })]));
    },
    /** The trial records no settings it began with: only a what-if can run (`why`: the server's words). */
    notRecorded(why) {
      radio(modeRecorded).disabled = true;
      radio(modeWhatIf).checked = true;
      showMode();
      modeNote.textContent = why;
      rerunStart.textContent = "This trial does not record the settings it began with, so a re-run cannot start from what "
        + "ran: it holds the settings below over the whole trial.";
    },
    /** The settings the editor starts from. */
    setBaseline(settings) {
      editor.setBaseline(settings);
    },
  };
}
