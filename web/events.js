// The events list (setting changes, annotations, system and recording events, detected speed-change intents),
// newest first, each in plain words ("Torque gain 1.00 → 1.30, by clinician"), never a raw field name;
// `describeEvent` gives the same words to the live plots' markers, and the review's markers (review_markers.js).
// Names and units come from the one table of each (wire.js: `SETTING_NAMES` for the settings and the primary,
// `QUANTITY_NAMES` for an estimator's output such as the intent's desired speed, an estimator's `label`).

import { estimatorLabel, learnedModel } from "./estimators.js";
import { SETTING_LIMITS } from "./settings.js";
import { fmt, h } from "./ui.js";
import { ESTIMATORS, QUANTITY_NAMES, SETTING_NAMES } from "./wire.js";

/** Marker colours on timelines, per event kind. */
export const EVENT_COLORS = { setting: "#c2410c", annotation: "#0b5cad", recording: "#1d7a3a", system: "#4b5563",
  intent: "#a21caf" };

/** Units written after a value (a scale, "×", or a fraction are not). */
const SHOWN_UNITS = new Set(["N·m", "m/s", "m", "deg", "1/s", "%"]);

/** The gait-state quantity (`QUANTITY_NAMES` entry) an event field names when it is an estimator's output (the
 * intent's `desired_speed_m_s`), or null. */
function outputQuantity(field) {
  for (const info of Object.values(ESTIMATORS)) {
    const q = info.quantities[field];
    if (q && QUANTITY_NAMES[q]) return QUANTITY_NAMES[q];
  }
  return null;
}

/** A field's unit as people write it, when a value is written with one ("" otherwise). */
export function fieldUnit(field) {
  const unit = SETTING_NAMES[field] ? SETTING_NAMES[field].unit : (outputQuantity(field) || { unit: "" }).unit;
  return SHOWN_UNITS.has(unit) ? unit : "";
}

/** A value of a field in words: an estimator by its label, a learned model's version, a number with its unit. */
export function valueText(field, v) {
  if (v === null || v === undefined) return "–";
  if (field === "primary" && typeof v === "string") return estimatorLabel(v);
  if (learnedModel(field) && typeof v === "number") return `v${Math.round(v)}`; // a learned model's versions
  if (typeof v === "number") {
    const unit = fieldUnit(field);
    return `${fmt(v, (SETTING_LIMITS[field] && SETTING_LIMITS[field].digits) || 3)}${unit ? ` ${unit}` : ""}`;
  }
  return String(v);
}

/** What each kind of event is called on screen. */
export const KIND_NAMES = { setting: "Setting", annotation: "Note", system: "System", recording: "Recording", intent: "Intent" };

/** A field's name on screen: a setting's, an estimator's output's quantity's, a learned model's. */
export function fieldName(field) {
  if (SETTING_NAMES[field]) return SETTING_NAMES[field].name;
  const q = outputQuantity(field);
  if (q) return q.name;
  return learnedModel(field) || field.replace(/_/g, " ").replace(/^./, (c) => c.toUpperCase());
}

const _shown = valueText;

/** A change of a clinician's setting (or of the primary estimator): one line, its author in it. */
export const isSettingChange = (ev) => ev.kind === "setting" && (!!SETTING_LIMITS[ev.field] || ev.field === "primary");

/**
 * An event in plain words: `headline` (a setting change as "Torque gain 1.00 → 1.30, by clinician", an
 * undo saying so; any other event as its text, its author shown apart) and `short` (for a marker on a plot).
 * @returns {{headline: string, short: string, undo: boolean}}
 */
export function describeEvent(ev) {
  const by = ev.actor && ev.actor !== "system" ? `, by ${ev.actor}` : "";
  if (isSettingChange(ev)) {
    const undo = /\(undo of /.test(ev.text || "");
    const change = `${fieldName(ev.field)} ${_shown(ev.field, ev.before)} → ${_shown(ev.field, ev.after)}`;
    return { headline: `${change}${undo ? " (undo of the previous change)" : ""}${by}`, short: `${undo ? "Undo: " : ""}${change}`, undo };
  }
  if (ev.kind === "annotation") return { headline: ev.text, short: `Note: ${ev.text}`, undo: false };
  const text = ev.text ? ev.text.charAt(0).toUpperCase() + ev.text.slice(1) : "";
  return { headline: text, short: text, undo: false };
}

/** A bounded list of `Event`s (at most `max`, newest kept), deduplicated by id. */
export class EventList {
  constructor(testid = "events-list", { max = 500, onSelect = null } = {}) {
    this.max = max;
    this.onSelect = onSelect;
    this.events = new Map();
    this.body = h("tbody", {});
    this.el = h("div", { class: "events-scroll" },
      h("table", { class: "table events", "data-testid": testid },
        h("thead", {}, h("tr", {}, h("th", { text: "Time (s)" }), h("th", { text: "What happened, and who did it" }))),
        this.body));
    this._render();
  }

  /** Adds events (from `GET .../events` or an `EventMessage`). */
  add(...events) {
    for (const ev of events) this.events.set(ev.id, ev);
    if (this.events.size > this.max) {
      const keep = this.sorted().slice(0, this.max);
      this.events = new Map(keep.map((e) => [e.id, e]));
    }
    this._render();
  }

  /** Newest first (by session time, then id). */
  sorted() {
    return [...this.events.values()].sort((a, b) => b.t - a.t || b.id - a.id);
  }

  _render() {
    const rows = this.sorted().map((ev) => {
      const { headline, undo } = describeEvent(ev);
      // a change of a field that is not a setting (a GP-EKF model, a calibration) keeps its own line
      const setting = isSettingChange(ev);
      const other = ev.field && !setting
        ? `${fieldName(ev.field)}: ${_shown(ev.field, ev.before)} → ${_shown(ev.field, ev.after)}` : "";
      const tr = h("tr", { "data-testid": "event-row", "data-kind": ev.kind, "data-id": ev.id, class: `kind-${ev.kind}${undo ? " undo" : ""}` },
        h("td", { class: "num", text: fmt(ev.t, 1) }),
        h("td", {},
          h("div", {}, h("span", { class: "kind", style: `border-color:${EVENT_COLORS[ev.kind] || "#4b5563"}`, text: KIND_NAMES[ev.kind] || ev.kind }), " ",
            h("span", { class: "text", "data-testid": "event-text", text: headline })),
          other ? h("div", { class: "change", "data-testid": "event-change", text: other }) : null,
          !setting && ev.actor && ev.actor !== "system"
            ? h("div", { class: "hint", "data-testid": "event-actor", text: `by ${ev.actor}` }) : null));
      if (this.onSelect) {
        tr.classList.add("clickable");
        tr.tabIndex = 0;
        tr.addEventListener("click", () => this.onSelect(ev));
        tr.addEventListener("keydown", (e) => {
          if (e.key === "Enter") this.onSelect(ev);
        });
      }
      return tr;
    });
    this.body.replaceChildren(...(rows.length ? rows : [h("tr", {}, h("td", { colspan: 2, class: "empty", text: "No events yet." }))]));
  }
}
