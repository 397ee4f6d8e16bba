// The new-session form's "Estimators" fieldset (sessions.js): the default stack (every estimator the source feeds
// but the opt-in ones), or a choice among every registered estimator (`GET /api/estimators`: its name on screen,
// the channels it needs, what it is for, its paper, what one sample costs on this server), with the chosen one
// that the torque follows (one that estimates a phase). Sent as the session's `settings.estimators` and
// `settings.primary`; the server stays the judge: a choice the source cannot feed is refused when the session
// starts (409 naming what is missing), shown in the form's error box.

import * as api from "./api_client.js";
import { listText } from "./estimators.js";
import { field, h, ValidationError } from "./ui.js";
import { DEFAULT_SETTINGS, ESTIMATORS } from "./wire.js";

/** @typedef {import("./wire.js").RegisteredEstimator} RegisteredEstimator */

/** What a custom choice starts from: the estimator the torque follows by default. */
const FIRST = DEFAULT_SETTINGS.primary;

/** "about 19 µs per sample on this server" (or that it was not timed). @param {number | null} us */
export function costText(us) {
  if (us === null || us === undefined || !Number.isFinite(us)) return "not timed on this server";
  return `about ${us < 10 ? us.toFixed(1) : Math.round(us)} µs per sample on this server`;
}

/** The channels an estimator needs, in words: its required ones, then "a or b" for those it needs one of. */
export function needsText(e) {
  const needs = [...e.inputs, ...(e.inputs_any.length ? [e.inputs_any.join(" or ")] : [])];
  return needs.length ? `needs ${needs.join(", ")}` : "needs no channel of its own";
}

export class SessionEstimators {
  constructor() {
    /** @type {RegisteredEstimator[]} */
    this.registered = [];
    /** @type {Map<string, HTMLInputElement>} name -> its checkbox */
    this.boxes = new Map();
    const radio = (value, text) => h("label", { class: "choice" },
      h("input", { type: "radio", name: "estimators-mode", value, "data-testid": `estimators-${value}`, checked: value === "default" }),
      h("span", { text }));
    this.list = h("div", { class: "estimator-list", "data-testid": "session-estimator-list", hidden: true });
    this.primary = h("select", { id: "session-primary", "data-testid": "session-primary" });
    this.primaryField = field("Torque follows", this.primary, "one of the chosen estimators that estimate a phase");
    this.primaryField.hidden = true;
    this.hint = h("p", { class: "hint", id: "session-estimators-hint", "data-testid": "session-estimators-hint",
      text: "Loading the estimators…" });
    this.el = h("fieldset", { class: "choices estimator-picker", "data-testid": "session-estimators",
      "aria-describedby": "session-estimators-hint" },
    h("legend", { text: "Estimators" }),
    radio("default", "Default (every estimator the source feeds)"),
    radio("custom", "Choose them"),
    this.list, this.primaryField, this.hint);
    this.el.style.minWidth = "0"; // a fieldset is at least as wide as its longest word: it stays in its column
    this.list.style.overflowWrap = "anywhere"; // channel names are long words
    this.el.addEventListener("change", () => this.sync());
    this.load();
  }

  /** Fetches the registered estimators (and their cost here); without them only the default can be sent. */
  async load() {
    try {
      this.show(await api.listEstimators());
    } catch {
      this.hint.textContent = "The estimators could not be loaded: the session runs the default stack.";
      this.mode("custom").disabled = true;
      this.mode("default").checked = true;
      this.sync();
    }
  }

  /** @param {"default" | "custom"} value */
  mode(value) {
    return /** @type {HTMLInputElement} */ (this.el.querySelector(`input[name=estimators-mode][value=${value}]`));
  }

  get custom() {
    return this.mode("custom").checked;
  }

  /**
   * One checkbox per registered estimator, in the order a stack runs them; the front ends deriving channels (for a
   * device that sends raw IMUs, or no centre of mass) folded under the others.
   * @param {RegisteredEstimator[]} list
   */
  show(list) {
    this.registered = list;
    this.boxes.clear();
    const rows = list.map((e) => this.row(e));
    const fronts = rows.filter((_, i) => list[i].derives);
    this.list.replaceChildren(...rows.filter((_, i) => !list[i].derives), fronts.length ? h("details",
      { class: "estimator-front-ends", "data-testid": "session-estimator-front-ends" },
      h("summary", { text: `Front ends deriving channels (${fronts.length}): for a device that sends raw IMUs, or no centre of mass` }),
      ...fronts) : null);
    this.sync();
  }

  /** An estimator's checkbox, with its name on screen, what it is for, what it needs and costs, its paper. */
  row(e) {
    const box = h("input", { type: "checkbox", name: "session-estimator", value: e.name, id: `session-estimator-${e.name}`,
      "data-testid": `session-estimator-${e.name}`, checked: e.name === FIRST });
    this.boxes.set(e.name, /** @type {HTMLInputElement} */ (box));
    const roles = [e.opt_in ? "opt-in: runs only when chosen" : "", e.phase || e.derives ? "" : "no phase: cannot drive the torque"];
    return h("label", { class: "choice estimator", for: box.id, "data-testid": `session-estimator-row-${e.name}`,
      "data-opt-in": e.opt_in ? "true" : "false" },
    box, h("span", { class: "estimator-text" },
      h("span", { class: "estimator-name" }, h("span", { text: e.label }),
        e.opt_in ? h("span", { class: "hint", text: "(opt-in)" }) : null),
      h("span", { class: "hint", "data-testid": `session-estimator-purpose-${e.name}`, text: e.purpose }),
      h("span", { class: "hint", "data-testid": `session-estimator-needs-${e.name}`,
        text: [needsText(e), costText(e.cost_us), ...roles.filter(Boolean)].join("; ") }),
      e.paper ? h("span", { class: "hint", text: e.paper }) : null));
  }

  /** The chosen estimators, in the order a stack runs them. */
  chosen() {
    return [...this.boxes].filter(([, b]) => b.checked).map(([n]) => n);
  }

  /** Shows the list and the primary for a custom choice; the primary's options are the chosen ones with a phase. */
  sync() {
    const custom = this.custom;
    this.list.hidden = !custom;
    this.primaryField.hidden = !custom;
    const byName = new Map(this.registered.map((e) => [e.name, e]));
    const phased = this.chosen().filter((n) => byName.get(n)?.phase);
    const keep = this.primary.value;
    if (JSON.stringify(phased) !== JSON.stringify([...this.primary.options].map((o) => o.value))) {
      this.primary.replaceChildren(...phased.map((n) => h("option", { value: n,
        text: ESTIMATORS[n]?.quantities.phase === "stance_phase" ? `${byName.get(n).label} (stance phase)` : byName.get(n).label })));
    }
    this.primary.value = phased.includes(keep) ? keep : phased.includes(FIRST) ? FIRST : (phased[0] ?? "");
    this.primary.disabled = !phased.length;
    if (!this.registered.length) return;
    if (!custom) {
      this.hint.textContent = "The session runs every estimator its source's channels feed, except the opt-in ones; " +
        `the torque follows ${ESTIMATORS[FIRST]?.label ?? FIRST}.`;
      return;
    }
    const costs = this.chosen().map((n) => byName.get(n)?.cost_us);
    const total = costs.every((c) => typeof c === "number") ? costs.reduce((a, c) => a + c, 0) : null;
    this.hint.textContent = `${this.chosen().length} chosen${total === null || !costs.length ? "" : `, together ${costText(total)}`}. ` +
      "The server checks that the source can feed them when the session starts.";
  }

  /**
   * What `SessionCreate.settings` carries: nothing for the default stack; else the chosen estimators and the one
   * the torque follows. Throws a ValidationError (shown in the form) for a choice that cannot drive the torque.
   * @returns {import("./wire.js").SessionSettings | undefined}
   */
  settings() {
    if (!this.custom) return undefined;
    const chosen = this.chosen();
    if (!chosen.length) throw new ValidationError("Choose at least one estimator, or the default.");
    if (!this.primary.value) {
      const phased = listText(this.registered.filter((e) => e.phase).map((e) => e.label), "or");
      throw new ValidationError(`Choose at least one estimator with a phase (${phased}): the torque follows one.`);
    }
    return { estimators: chosen, primary: this.primary.value };
  }
}
