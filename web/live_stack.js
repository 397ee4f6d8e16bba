// The live view's estimator stack (live.js): the session's estimators with a gait phase (known from the first
// batch; `phased`: with any phase, the primary's choices), the one driving the torque, the failed ones, as the
// batches, health messages and setting changes tell them; shown in the data-health box, with the switch of
// the primary (a setting: validated, rate-limited and logged by the server).

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { sendByTorqueRule, torqueConfirmBox } from "./confirm_change.js";
import { estimatorLabel, STANCE_PHASE } from "./estimators.js";
import { errorBox, h, runAction } from "./ui.js";

export class LiveStack {
  /**
   * @param {number} sessionId
   * @param {Record<string, HTMLElement>} health the data-health box's fields (`primary`, `failedEstimators`)
   * @param {{setSession: (s: any) => void, primary: (primary: string | null) => void,
   *   stack: (names: string[], primary: string | null, failed: Set<string>) => void}} hooks the session after a
   *   switch; the primary shown (each time); the phase plot's stack (when it changed)
   */
  constructor(sessionId, health, hooks) {
    /** @type {string[]} */
    this.names = [];
    /** @type {string[]} */
    this.phased = [];
    /** @type {string | null} */
    this.primary = null;
    /** @type {Map<string, string>} */
    this.failed = new Map();
    this.key = "";
    this._health = health;
    this._hooks = hooks;
    this.select = h("select", { id: "primary-select", "data-testid": "primary-select", "aria-label": "Primary estimator" });
    const primaryBtn = h("button", { type: "button", "data-testid": "primary-apply", text: "Switch" });
    const primaryError = errorBox("primary-error");
    // switching the primary changes what drives the torque: it asks first, as every such change (confirm_change.js)
    const confirm = torqueConfirmBox("confirm-primary");
    primaryBtn.addEventListener("click", () => runAction(primaryBtn, primaryError, async () => {
      const change = { primary: this.select.value };
      const session = await sendByTorqueRule(sessionId, change, confirm,
        (yes) => api.changeSettings(sessionId, yes ? { ...change, confirm: true } : change),
        `Switch the estimator the torque follows to ${this.select.selectedOptions[0]?.textContent || change.primary}`);
      if (session) hooks.setSession(session);
    }));
    /** the primary's switch and its error, for the data-health box */
    this.els = [fence(h("div", { class: "inline", "data-testid": "primary-switch" },
      h("label", { for: "primary-select", text: "Torque follows " }), this.select, primaryBtn), "assist",
    "Only a clinician or an admin switches the estimator driving the torque."), confirm.el, primaryError];
  }

  /** The stack is known (or changed): the health box says it, the phase plot and the switch follow it. */
  show() {
    const health = this._health;
    const failed = new Set(this.failed.keys());
    health.primary.textContent = this.primary ? estimatorLabel(this.primary) : "none: the torque is 0";
    health.primary.classList.toggle("warn", !this.primary);
    health.failedEstimators.textContent = failed.size ? [...this.failed].map(([n, why]) => `${estimatorLabel(n)}: ${why}`).join("; ") : "none";
    health.failedEstimators.classList.toggle("warn", failed.size > 0);
    this._hooks.primary(this.primary);
    const key = JSON.stringify([this.names, this.phased, this.primary, [...failed]]);
    if (key === this.key || !this.phased.length) return; // the plot waits for the first batch's estimators
    this.key = key;
    this._hooks.stack(this.names, this.primary, failed);
    const options = this.phased.filter((n) => !failed.has(n));
    if (JSON.stringify(options) !== JSON.stringify([...this.select.options].map((o) => o.value))) {
      this.select.replaceChildren(...options.map((n) => h("option", { value: n, text: estimatorLabel(n) })));
    }
    if (this.primary && options.includes(this.primary)) this.select.value = this.primary;
  }

  /** A batch's `estimators`: which have a phase, which failed. */
  fromBatch(est) {
    const phased = Object.keys(est).filter((n) => est[n].columns && est[n].columns.phase);
    if (phased.length && JSON.stringify(phased) !== JSON.stringify(this.phased)) {
      this.phased = phased;
      this.names = phased.filter((n) => !STANCE_PHASE.has(n));
      this.show();
    }
    for (const [n, e] of Object.entries(est)) {
      if (e.failed && !this.failed.has(n)) {
        this.failed.set(n, "failed");
        this.show();
      }
    }
  }

  /** A health message that names the stack: its primary and failures. */
  fromHealth(m) {
    this.primary = m.primary ?? null;
    this.failed = new Map(Object.entries(m.failed_estimators || {}));
    this.show();
  }

  /** A settings message: its primary, until the next health message says otherwise. */
  fromSettings(settings) {
    if (settings.primary && !this.failed.has(settings.primary)) {
      this.primary = settings.primary;
      this.show();
    }
  }
}
