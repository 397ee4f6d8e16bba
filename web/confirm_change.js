// The torque rule in the browser (issue #23, 4): a settings change that can raise the torque on the person (a raise
// of the torque gain, the maximum torque or the intent boost, a switch of the primary, an undo that does one of
// those) asks first, naming the peak torque before and after, as the server computes them
// (`POST .../settings/check`, gaitscope.sessions.live.torque_rule); only then is it sent, with `confirm`. The server
// judges it again: a change it finds raising without `confirm` (an undo, whose values only the server knows) comes
// back as a 409 with the same peaks, and is asked and resent. Lowering never asks.

import { ApiError } from "./api.js";
import * as api from "./api_client.js";
import { fmt, h, ValidationError } from "./ui.js";
import { SETTING_NAMES, TORQUE_RULE } from "./wire.js";

/** "torque gain, torque follows": the settings of a change in words. */
function fieldsText(fields) {
  return fields.map((f) => (SETTING_NAMES[f] ? SETTING_NAMES[f].name : f).toLowerCase()).join(", ");
}

/**
 * A confirmation box, hidden until asked. Test ids: `${prefix}-box`, `-text`, `-before`, `-after`, the confirming
 * button `${prefix}` and `${prefix}-cancel`.
 * @param {string} prefix
 */
export function torqueConfirmBox(prefix) {
  const text = h("p", { "data-testid": `${prefix}-text` });
  const before = h("strong", { "data-testid": `${prefix}-before` });
  const after = h("strong", { "data-testid": `${prefix}-after` });
  const peaks = h("p", { class: "confirm-peaks" }, "Peak torque over a stride: ", before, " → ", after);
  const yes = h("button", { type: "button", class: "danger", "data-testid": prefix, text: "Confirm" });
  const no = h("button", { type: "button", "data-testid": `${prefix}-cancel`, text: "Cancel" });
  const note = h("p", { class: "hint", text: `At most one change that can raise the torque every ${TORQUE_RULE.interval_s} s; lowering never asks.` });
  const el = h("div", { class: "confirm-box", role: "alertdialog", "aria-label": "Confirm a change that can raise the torque",
    "data-testid": `${prefix}-box`, hidden: true }, text, peaks, note, h("div", { class: "buttons" }, yes, no));
  /** @type {((ok: boolean) => void) | null} */
  let answer = null;
  const settle = (ok) => {
    el.hidden = true;
    const a = answer;
    answer = null;
    if (a) a(ok);
  };
  yes.addEventListener("click", () => settle(true));
  no.addEventListener("click", () => settle(false));
  return {
    el,
    /**
     * Ask about a change the server says can raise the torque; resolves true when confirmed.
     * @param {{fields: string[], peak_before_Nm: number, peak_after_Nm: number}} check
     * @param {string} [what] the change in words (default: its settings)
     * @returns {Promise<boolean>}
     */
    ask(check, what) {
      settle(false); // a question still open is answered "no"
      const rises = check.peak_after_Nm > check.peak_before_Nm;
      const why = check.fields.includes("primary") ? " (another estimator drives it)"
        : rises ? "" : " (not its peak at the present gait state, but at others)";
      text.textContent = `${what || `Change ${fieldsText(check.fields)}`}? This can raise the torque on the person${why}.`;
      before.textContent = `${fmt(check.peak_before_Nm, 1)} N·m`;
      after.textContent = `${fmt(check.peak_after_Nm, 1)} N·m`;
      yes.textContent = check.fields.includes("primary") ? "Switch it" : rises ? "Raise it" : "Confirm";
      el.hidden = false;
      yes.focus();
      return new Promise((resolve) => { answer = resolve; });
    },
    /** Close the box, as cancelled. */
    cancel() {
      settle(false);
    },
  };
}

/** The refusal of a change for want of `confirm` (the server's TorqueRaiseRefused), else null. */
function needsConfirm(err) {
  const d = err instanceof ApiError && err.status === 409 ? err.detail : null;
  return d && typeof d === "object" && !Array.isArray(d) && d.reason === "confirm" ? d : null;
}

/**
 * Send a settings change by the torque rule: asked first (with the peaks) when it can raise the torque, then sent
 * with `confirm`; null when the user cancelled. `change`: the settings asked for (null: not known here, an undo).
 * @param {number} sessionId
 * @param {object | null} change
 * @param {ReturnType<typeof torqueConfirmBox>} box
 * @param {(confirm: boolean) => Promise<any>} send
 * @param {string} [what] the change in words, for the question
 */
export async function sendByTorqueRule(sessionId, change, box, send, what) {
  let confirm = false;
  if (change) {
    const check = await api.checkSettings(sessionId, change);
    if (check.fields.length) {
      if (check.retry_after_s > 0) {
        throw new ValidationError(`Not yet: a change that can raise the torque (${fieldsText(check.fields)}) may be made ` +
          `at most every ${TORQUE_RULE.interval_s} s; try again in ${check.retry_after_s.toFixed(1)} s.`);
      }
      if (!(await box.ask(check, what))) return null;
      confirm = true;
    }
  }
  try {
    return await send(confirm);
  } catch (err) {
    const asked = confirm ? null : needsConfirm(err);
    if (!asked) throw err;
    if (!(await box.ask(asked, what))) return null;
    return send(true);
  }
}
