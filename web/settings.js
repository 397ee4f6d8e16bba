// The clinician-adjustable settings: bounds, and an editor (number box + slider per setting) used by
// the live view's "Apply" and the review view's "Re-run with settings". Every slider spans the setting's
// absolute range (its bounds in sessions/schema.py), so that where its thumb sits says the value: 40 of 0–80 N·m
// sits in the middle (issue #23, 6). In the live view (`rateLimited`) each row shows the value applied now beside
// the one being edited, and the rate limit as such, in words beside the slider ("up to ±10 per change", and how
// long until the field may change again), never by narrowing the slider. Lowering the torque gain, the maximum
// torque or the intent boost is never held back (gaitscope.sessions.live.torque_rule).

import { SETTING_LIMITS as WIRE_LIMITS, SETTING_NAMES, TORQUE_RULE } from "./wire.js";
import { fmt, h, ValidationError } from "./ui.js";

/** How each setting is stepped and shown; its name and unit come from the schema (SETTING_NAMES), its bounds too. */
const PRESENTATION = {
  torque_gain: { step: 0.05, digits: 2 },
  max_torque_Nm: { step: 1, digits: 1 },
  measurement_noise_scale: { step: 0.1, digits: 2 },
  process_noise_scale: { step: 0.1, digits: 2 },
  // sessions/intent_boost.py: gain x (1 ± boost x confidence) while the intent estimator says speeding up / slowing down
  intent_gain_boost: { step: 0.05, digits: 2, hint: "assistance follows intent, 0 = off" },
};

/** A setting's name on screen (with its hint, if any) and unit: one table, the schema's. */
function named(key) {
  const n = SETTING_NAMES[key];
  const hint = PRESENTATION[key] && PRESENTATION[key].hint;
  return n ? { label: hint ? `${n.name}: ${hint}` : n.name, unit: n.unit } : { label: key, unit: "" };
}

/**
 * Each setting: min, max and largest change per second from SETTING_LIMITS in sessions/schema.py (via the
 * generated wire.js), with how it is shown. The server remains the judge (422, 409).
 * @type {Readonly<Record<string, {label: string, unit: string, step: number, digits: number, min: number, max: number, rate: number}>>}
 */
export const SETTING_LIMITS = Object.freeze(Object.fromEntries(Object.entries(WIRE_LIMITS).map(
  ([key, lim]) => [key, Object.freeze({ step: 0.1, digits: 3, ...PRESENTATION[key], ...named(key), ...lim })])));

export const SETTING_KEYS = Object.keys(SETTING_LIMITS);

const _EPS = 1e-9;

/** One editor row per setting; `prefix` names ids and test ids (e.g. "setting" -> "setting-torque_gain"). */
export class SettingsEditor {
  constructor(prefix, { rateLimited = false } = {}) {
    this.prefix = prefix;
    this.rateLimited = rateLimited;
    this.baseline = {};
    this.changedAt = {}; // performance.now() of each field's last change seen (the rate limit counts from it)
    this.rows = {};
    this.el = h("div", { class: "settings-editor" });
    for (const key of SETTING_KEYS) this._addRow(key);
  }

  _addRow(key) {
    const lim = SETTING_LIMITS[key];
    const id = `${this.prefix}-${key}`;
    const number = h("input", {
      type: "number", id, name: key, min: lim.min, max: lim.max, step: lim.step, inputmode: "decimal",
      "data-testid": id, "aria-describedby": `${id}-hint`,
    });
    const slider = h("input", {
      type: "range", min: lim.min, max: lim.max, step: lim.step, "data-testid": `${id}-slider`,
      "aria-label": `${lim.label} slider`,
    });
    const note = h("span", { class: "note", "data-testid": `${id}-note` });
    const applied = h("span", { class: "applied", "data-testid": `${id}-applied`, hidden: !this.rateLimited });
    // the rate limit, shown as such: the largest step of one change, and the wait before the next one
    const rate = h("span", { class: "rate-limit", "data-testid": `${id}-rate`, hidden: !this.rateLimited,
      text: `up to ±${lim.rate} per change` });
    const hint = h("span", {
      class: "hint", id: `${id}-hint`,
      text: `${lim.min}–${lim.max} ${lim.unit}; at most ±${lim.rate} per second`,
    });
    number.addEventListener("input", () => {
      if (number.value !== "" && Number.isFinite(Number(number.value))) slider.value = number.value;
      this._markDirty(key);
    });
    slider.addEventListener("input", () => {
      number.value = slider.value;
      this._markDirty(key);
    });
    const row = h("div", { class: "setting-row" },
      h("label", { for: id, class: "caption", text: `${lim.label} (${lim.unit})` }),
      h("div", { class: "setting-inputs" }, number, slider, applied), rate, hint, note);
    this.rows[key] = { number, slider, note, applied, rate, row, dirty: false };
    this.el.append(row);
  }

  _markDirty(key) {
    const r = this.rows[key];
    r.dirty = Math.abs(Number(r.number.value) - this.baseline[key]) > _EPS || r.number.value === "";
    r.row.classList.toggle("dirty", r.dirty);
  }

  /**
   * The server's current settings. Untouched fields follow them; a field the user is editing keeps the
   * edit and says what it was changed to elsewhere.
   */
  setBaseline(settings, { fromElsewhere = false } = {}) {
    for (const key of SETTING_KEYS) {
      if (!(key in settings)) continue;
      const v = settings[key];
      const r = this.rows[key];
      const changed = this.baseline[key] !== undefined && Math.abs(v - this.baseline[key]) > _EPS;
      if (changed) this.changedAt[key] = performance.now();
      this.baseline[key] = v;
      r.applied.textContent = `applied now: ${fmt(v, SETTING_LIMITS[key].digits)}`;
      if (!r.dirty) {
        r.number.value = String(v);
        r.slider.value = String(v);
        r.note.textContent = changed && fromElsewhere ? `changed elsewhere to ${fmt(v, SETTING_LIMITS[key].digits)}` : "";
      } else {
        r.note.textContent = changed ? `server now ${fmt(v, SETTING_LIMITS[key].digits)}` : r.note.textContent;
      }
      this._markDirty(key);
    }
    this.showRateLimits();
  }

  /**
   * The largest step each field may take now: its rate limit, times the seconds since it last changed
   * (at most one second's worth), as the server counts it.
   * @returns {Record<string, number>}
   */
  reachable(now = performance.now()) {
    /** @type {Record<string, number>} */
    const out = {};
    for (const key of SETTING_KEYS) {
      const { rate } = SETTING_LIMITS[key];
      const since = this.changedAt[key] === undefined ? Infinity : (now - this.changedAt[key]) / 1000;
      out[key] = rate * Math.min(1, since);
    }
    return out;
  }

  /**
   * Live view: beside each slider, its rate limit in words: the largest step of one change and, just after a
   * change, how long until the next (call a few times a second). The slider keeps its absolute range.
   */
  showRateLimits(now = performance.now()) {
    if (!this.rateLimited) return;
    const reach = this.reachable(now);
    for (const key of SETTING_KEYS) {
      const lim = SETTING_LIMITS[key];
      const r = this.rows[key];
      const lowers = TORQUE_RULE.raising.includes(key) ? "; lowering: any step, at any time" : "";
      const wait = reach[key] < lim.rate - 1e-9 && this.changedAt[key] !== undefined
        ? ` (now up to ±${+reach[key].toFixed(3)}: the full step ${((1000 - (now - this.changedAt[key])) / 1000).toFixed(1)} s after the last change)`
        : "";
      const text = `up to ±${lim.rate} per change${wait}${lowers}`;
      if (r.rate.textContent !== text) r.rate.textContent = text;
    }
  }

  /** Every field, validated against its bounds. @throws {ValidationError} */
  values() {
    const out = {};
    for (const key of SETTING_KEYS) {
      const lim = SETTING_LIMITS[key];
      const raw = this.rows[key].number.value.trim();
      const x = Number(raw);
      if (raw === "" || !Number.isFinite(x)) throw new ValidationError(`${lim.label} must be a number.`);
      if (x < lim.min || x > lim.max) {
        throw new ValidationError(`${lim.label} must be between ${lim.min} and ${lim.max} (got ${raw}).`);
      }
      out[key] = x;
    }
    return out;
  }

  /** Only the fields that differ from the server's values (validated). @throws {ValidationError} */
  changes() {
    const all = this.values();
    const out = {};
    for (const key of SETTING_KEYS) {
      const step = Math.abs(all[key] - this.baseline[key]);
      if (step <= _EPS) continue;
      out[key] = all[key];
      // lowering the torque is never held back (the server's torque rule): any step, at any time
      if (TORQUE_RULE.raising.includes(key) && all[key] < this.baseline[key]) continue;
      // The server also limits how soon a field may change again (409, with the wait in its message).
      const lim = SETTING_LIMITS[key];
      if (step > lim.rate + _EPS) {
        throw new ValidationError(`${lim.label} may change by at most ${lim.rate} per step ` +
          `(${this.baseline[key]} → ${all[key]} is a step of ${+step.toFixed(6)}); apply it in smaller steps.`);
      }
    }
    return out;
  }

  /** Forgets edits: every field back to the server's value. */
  revert() {
    for (const key of SETTING_KEYS) {
      const r = this.rows[key];
      r.dirty = false;
      r.note.textContent = "";
    }
    this.setBaseline({ ...this.baseline });
  }
}
