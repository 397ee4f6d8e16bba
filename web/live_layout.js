// The live page's panels: which are shown, their order and width, remembered per acting user (localStorage,
// keyed by the name chosen in "Acting as"), with a menu to change them and a reset. The session's Stop, LIVE, the
// recording state and the summary figures are not panels: they stay in the status strip above (live_status.js).

import { h } from "./ui.js";

/** Widths a panel may take, in columns of the page's grid (three on a wide screen, two on a tablet). */
export const SIZES = { 1: "narrow", 2: "wide", 3: "full width" };

const _KEY = "gaitscope.live.layout.";
const _NAMED = "gaitscope.live.layouts."; // the user's named layouts: {name: layout}
/** What an exported layout file says it is (PlotJuggler and Foxglove users keep layouts as files too). */
export const LAYOUT_FORMAT = "gaitscope.live.layout/1";

/**
 * A stored layout made to fit the panels there are: unknown ids dropped, missing ones added in their default
 * place, sizes checked; null for what cannot be read.
 * @param {any} stored parsed JSON, of any shape @param {{id: string, size: number}[]} panels defaults, in order
 * @returns {{order: string[], size: Record<string, number>, hidden: string[]}}
 */
export function normalizeLayout(stored, panels) {
  const ids = panels.map((p) => p.id);
  const base = { order: ids, size: Object.fromEntries(panels.map((p) => [p.id, p.size])), hidden: [] };
  if (!stored || typeof stored !== "object" || !Array.isArray(stored.order)) return base;
  const order = stored.order.filter((id, i) => ids.includes(id) && stored.order.indexOf(id) === i);
  for (const id of ids) {
    if (!order.includes(id)) order.splice(Math.min(ids.indexOf(id), order.length), 0, id);
  }
  const size = { ...base.size };
  for (const [id, n] of Object.entries(stored.size || {})) if (ids.includes(id) && SIZES[n]) size[id] = Number(n);
  const hidden = Array.isArray(stored.hidden) ? stored.hidden.filter((id) => ids.includes(id)) : [];
  return { order, size, hidden };
}

/**
 * The live page's panels in their default order, from their elements: the key plots (`keyBox`),
 * data health, the controls' cards (`controls`: settings, annotation, recording, imu), the
 * per-stride overlays, the events, the more plots, the leg view, the GP-EKF card and the device credentials.
 * @param {Record<string, any>} els
 * @returns {{id: string, title: string, size: number, el: HTMLElement}[]}
 */
export function livePanels(els) {
  const card = (id, heading, ...body) => h("section", { class: "card", "data-testid": `${id}-card` }, h("h2", { text: heading }), ...body);
  const c = els.controls;
  return [
    { id: "key-plots", title: "Key plots", size: 2, el: card("key-plots", "Phase, torque, phase rate, incline", els.keyBox) },
    { id: "health", title: "Data health", size: 1, el: els.health },
    { id: "settings", title: "Assistance settings", size: 1, el: c.settings },
    { id: "overlays", title: "Per-stride overlays", size: 2, el: els.overlays },
    { id: "events", title: "Events", size: 1, el: card("events", "Events (newest first)", els.events) },
    { id: "more-plots", title: "More plots", size: 2, el: card("more-plots", "Stride length, foot, shank, hip and knee", els.moreBox) },
    { id: "annotation", title: "Annotation", size: 1, el: c.annotation },
    { id: "recording", title: "Recording", size: 1, el: c.recording },
    { id: "leg", title: "3D leg view", size: 1, el: els.leg },
    { id: "imu", title: "IMU calibration", size: 1, el: c.imu },
    { id: "gp", title: "GP-EKF learning", size: 3, el: els.gp },
    { id: "credentials", title: "Device credentials", size: 1, el: els.credentials },
  ];
}

/**
 * The panel grid. `panels`: [{id, title, size (1-3), el}] in their default order.
 * `user` names whose layout is shown (the logged-in user's); `use(user)` switches to another's.
 */
export class PanelLayout {
  constructor(panels, user) {
    this.panels = panels;
    this.actor = user;
    this.grid = h("div", { class: "live-panels", "data-testid": "live-panels" });
    this.wraps = {};
    for (const p of panels) {
      p.el.classList.add("panel");
      p.el.dataset.panel = p.id;
      p.el.dataset.testid = p.el.dataset.testid || `panel-${p.id}`;
      this.wraps[p.id] = p.el;
      this.grid.append(p.el);
    }
    this.menuBody = h("div", { class: "layout-rows" });
    const reset = h("button", { type: "button", "data-testid": "layout-reset", text: "Back to the standard layout" });
    reset.addEventListener("click", () => {
      localStorage.removeItem(this._key());
      this.load();
    });
    this.named = namedLayouts(this);
    this.menu = h("details", { class: "layout-menu", "data-testid": "layout-menu" },
      h("summary", { text: "Panels" }),
      h("div", { class: "layout-pop" }, h("p", { class: "hint", "data-testid": "layout-owner" }), this.menuBody, reset, this.named.el));
    this.load();
  }

  /** The named layouts of the acting user: {name: layout}. */
  saved() {
    try {
      const all = JSON.parse(localStorage.getItem(_NAMED + this.actor) || "{}");
      return all && typeof all === "object" && !Array.isArray(all) ? all : {};
    } catch {
      return {};
    }
  }

  /** Keeps the current layout under `name` (replacing one of that name). */
  saveAs(name) {
    const all = this.saved();
    all[name] = { ...this.layout };
    localStorage.setItem(_NAMED + this.actor, JSON.stringify(all));
    this.named.render();
  }

  /** Shows the named layout `name` (and keeps it as the current one). */
  useNamed(name) {
    const stored = this.saved()[name];
    if (!stored) return;
    this.layout = normalizeLayout(stored, this.panels);
    this._save();
  }

  forget(name) {
    const all = this.saved();
    delete all[name];
    localStorage.setItem(_NAMED + this.actor, JSON.stringify(all));
    this.named.render();
  }

  /** The current layout as a file's JSON text, named. */
  exportJson(name) {
    const { order, size, hidden } = this.layout;
    return JSON.stringify({ format: LAYOUT_FORMAT, name, order, size, hidden }, null, 2);
  }

  /**
   * A layout file's text: shown and kept under its name; throws an Error in plain words when it is not one.
   * @returns {string} its name
   */
  importJson(text) {
    let data;
    try {
      data = JSON.parse(text);
    } catch {
      throw new Error("This file is not JSON: not a gaitscope layout.");
    }
    if (!data || data.format !== LAYOUT_FORMAT || !Array.isArray(data.order)) {
      throw new Error(`This file is not a gaitscope live layout (its "format" is not ${LAYOUT_FORMAT}).`);
    }
    const name = String(data.name || "imported").slice(0, 60);
    this.layout = normalizeLayout(data, this.panels);
    this._save();
    this.saveAs(name);
    return name;
  }

  _key() {
    return _KEY + this.actor;
  }

  /** Shows the acting user's layout (or the standard one). */
  load() {
    let stored = null;
    try {
      stored = JSON.parse(localStorage.getItem(this._key()) || "null");
    } catch {
      stored = null; // unreadable: the standard layout
    }
    this.layout = normalizeLayout(stored, this.panels);
    this._apply();
  }

  /** Another user acts: their layout. */
  use(user) {
    this.actor = user;
    this.load();
    this.named.render();
  }

  _save() {
    localStorage.setItem(this._key(), JSON.stringify(this.layout));
    this._apply();
  }

  move(id, by) {
    const order = this.layout.order;
    const i = order.indexOf(id);
    const j = i + by;
    if (i < 0 || j < 0 || j >= order.length) return;
    [order[i], order[j]] = [order[j], order[i]];
    this._save();
  }

  resize(id, n) {
    this.layout.size[id] = n;
    this._save();
  }

  show(id, shown) {
    this.layout.hidden = this.layout.hidden.filter((x) => x !== id);
    if (!shown) this.layout.hidden.push(id);
    this._save();
  }

  _apply() {
    const { order, size, hidden } = this.layout;
    order.forEach((id, i) => {
      const el = this.wraps[id];
      el.style.order = String(i);
      el.dataset.size = String(size[id]);
      el.classList.toggle("panel-hidden", hidden.includes(id));
    });
    this.menu.querySelector("[data-testid=layout-owner]").textContent =
      `The layout of ${this.actor} (kept in this browser for this user).`;
    const title = Object.fromEntries(this.panels.map((p) => [p.id, p.title]));
    this.menuBody.replaceChildren(...order.map((id, i) => {
      const shown = h("input", { type: "checkbox", "data-testid": `layout-show-${id}`, "aria-label": `Show ${title[id]}` });
      shown.checked = !hidden.includes(id);
      shown.addEventListener("change", () => this.show(id, shown.checked));
      const up = h("button", { type: "button", "data-testid": `layout-up-${id}`, "aria-label": `Move ${title[id]} earlier`, text: "↑", disabled: i === 0 });
      const down = h("button", { type: "button", "data-testid": `layout-down-${id}`, "aria-label": `Move ${title[id]} later`, text: "↓", disabled: i === order.length - 1 });
      up.addEventListener("click", () => this.move(id, -1));
      down.addEventListener("click", () => this.move(id, 1));
      const width = h("select", { "data-testid": `layout-size-${id}`, "aria-label": `Width of ${title[id]}` },
        ...Object.entries(SIZES).map(([n, label]) => h("option", { value: n, text: label })));
      width.value = String(size[id]);
      width.addEventListener("change", () => this.resize(id, Number(width.value)));
      return h("div", { class: "layout-row" }, h("label", {}, shown, ` ${title[id]}`), up, down, width);
    }));
  }
}

/**
 * The menu's named layouts: save the current one under a name, use or delete a saved one, export it as a JSON
 * file and import one.
 * @param {PanelLayout} layout
 */
function namedLayouts(layout) {
  const name = h("input", { type: "text", maxlength: 60, "data-testid": "layout-name", placeholder: "e.g. treadmill, clinic",
    "aria-label": "Name of the layout to save" });
  const save = h("button", { type: "button", "data-testid": "layout-save", text: "Save as" });
  const pick = h("select", { "data-testid": "layout-saved", "aria-label": "Saved layouts" });
  const use = h("button", { type: "button", "data-testid": "layout-use", text: "Use" });
  const del = h("button", { type: "button", "data-testid": "layout-delete", text: "Delete" });
  const exp = h("button", { type: "button", "data-testid": "layout-export", text: "Export JSON" });
  const file = h("input", { type: "file", accept: ".json,application/json", "data-testid": "layout-import",
    "aria-label": "Import a layout (JSON file)" });
  const note = h("p", { class: "hint", role: "status", "data-testid": "layout-note" });
  const render = () => {
    const names = Object.keys(layout.saved()).sort();
    pick.replaceChildren(...(names.length ? names.map((n) => h("option", { value: n, text: n }))
      : [h("option", { value: "", text: "no saved layout yet" })]));
    pick.disabled = use.disabled = del.disabled = !names.length;
  };
  save.addEventListener("click", () => {
    const n = name.value.trim();
    if (!n) {
      note.textContent = "Name the layout first.";
      return;
    }
    layout.saveAs(n);
    pick.value = n;
    name.value = "";
    note.textContent = `Saved as “${n}”.`;
  });
  use.addEventListener("click", () => {
    layout.useNamed(pick.value);
    note.textContent = `Showing “${pick.value}”.`;
  });
  del.addEventListener("click", () => {
    const n = pick.value;
    layout.forget(n);
    note.textContent = `Deleted “${n}”.`;
  });
  exp.addEventListener("click", () => {
    const n = pick.value || "layout";
    const url = URL.createObjectURL(new Blob([layout.exportJson(n)], { type: "application/json" }));
    const a = h("a", { href: url, download: `gaitscope-layout-${n.replace(/[^\w.-]+/g, "_")}.json` });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 1000);
  });
  file.addEventListener("change", async () => {
    const f = file.files && file.files[0];
    if (!f) return;
    try {
      const n = layout.importJson(await f.text());
      render();
      pick.value = n;
      note.textContent = `Imported “${n}”.`;
    } catch (err) {
      note.textContent = err.message;
    }
    file.value = "";
  });
  const el = h("div", { class: "layout-named", "data-testid": "layout-named" },
    h("p", { class: "caption", text: "Named layouts" }),
    h("div", { class: "layout-line" }, name, save),
    h("div", { class: "layout-line" }, pick, use, del),
    h("div", { class: "layout-line" }, exp, h("label", { class: "button layout-file" }, "Import JSON", file)), note);
  render();
  return { el, render };
}
