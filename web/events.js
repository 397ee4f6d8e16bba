// The events list (setting changes, annotations, system and recording events, detected speed-change intents),
// newest first.

import { SETTING_LIMITS } from "./settings.js";
import { fmt, h } from "./ui.js";

/** Marker colours on timelines, per event kind. */
export const EVENT_COLORS = { setting: "#c2410c", annotation: "#0b5cad", recording: "#1d7a3a", system: "#4b5563",
  intent: "#a21caf" };

function _value(field, v) {
  if (v === null || v === undefined) return "–";
  if (field === "gp_ekf" && typeof v === "number") return `v${Math.round(v)}`; // the GP-EKF's model versions
  if (typeof v === "number") return fmt(v, (SETTING_LIMITS[field] && SETTING_LIMITS[field].digits) || 3);
  return String(v);
}

/** Event fields shown by another name than their machine name. */
const FIELD_NAMES = { gp_ekf: "GP-EKF model" };

/** A bounded list of `Event`s (at most `max`, newest kept), deduplicated by id. */
export class EventList {
  constructor(testid = "events-list", { max = 500, onSelect = null } = {}) {
    this.max = max;
    this.onSelect = onSelect;
    this.events = new Map();
    this.body = h("tbody", {});
    this.el = h("div", { class: "events-scroll" },
      h("table", { class: "table events", "data-testid": testid },
        h("thead", {}, h("tr", {}, h("th", { text: "t (s)" }), h("th", { text: "Event: what, before → after, who" }))),
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
      const change = ev.field ? `${FIELD_NAMES[ev.field] || ev.field}: ${_value(ev.field, ev.before)} → ${_value(ev.field, ev.after)}` : "";
      const tr = h("tr", { "data-testid": "event-row", "data-kind": ev.kind, "data-id": ev.id, class: `kind-${ev.kind}` },
        h("td", { class: "num", text: fmt(ev.t, 1) }),
        h("td", {},
          h("div", {}, h("span", { class: "kind", style: `border-color:${EVENT_COLORS[ev.kind] || "#4b5563"}`, text: ev.kind }), " ",
            h("span", { class: "text", "data-testid": "event-text", text: ev.text })),
          change ? h("div", { class: "change", "data-testid": "event-change", text: change }) : null,
          h("div", { class: "hint", "data-testid": "event-actor", text: `by ${ev.actor}` })));
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
