// The import preview of an upload (issue #25): what an import would read from the file's first seconds
// (`POST /api/uploads/{id}/preview`, ImportPreview), shown before anything is stored. The channels found (unit,
// range in the file against the plausible one, values outside it, a sparkline of each), the estimators the file
// feeds and what each of the others lacks, what is ignored, the warnings, and the problem the import would
// refuse the file for. A file that needs a channel mapping (another tool's MCAP recording, a C3D file) shows
// the mapping in use and where it came from, and lets the person edit it: a channel and a scale per field
// (MCAP) or the mapping's JSON (C3D). upload.js sends it and previews again; this module only draws.

import { estimatorLabel, listText } from "./estimators.js";
import { errorBox, fmt, h, showError, ValidationError } from "./ui.js";
import { SENSOR_LIMITS } from "./wire.js";

/**
 * @typedef {object} EstimatorFeed
 * @property {string} name
 * @property {string} label
 * @property {boolean} feedable its inputs are in the file or derived from it
 * @property {boolean} ran the import runs it (opt-in ones run in a re-run that names them)
 * @property {string[]} missing what it lacks ("a or b": either)
 * @property {Record<string, string[]>} derived inputs the file lacks that these estimators derive
 */
/**
 * @typedef {object} ImportReport
 * @property {string} format
 * @property {string[]} channels
 * @property {string[]} derived
 * @property {string[]} ignored
 * @property {EstimatorFeed[]} estimators
 * @property {string[]} warnings
 */
/**
 * @typedef {object} PreviewChannel
 * @property {string} channel
 * @property {string} unit
 * @property {string} source
 * @property {number} count
 * @property {number | null} min
 * @property {number | null} max
 * @property {[number, number] | null} plausible
 * @property {number} outside
 */
/**
 * @typedef {object} SourceField
 * @property {string} topic
 * @property {string} path
 * @property {string} kind number, bool, marker or analog
 * @property {number | null} count
 * @property {number | null} rate_hz
 * @property {number | null} min
 * @property {number | null} max
 * @property {string | null} channel the channel it is mapped to, or a C3D marker's role
 */
/**
 * @typedef {object} ImportPreview
 * @property {string} filename
 * @property {string} format
 * @property {number} previewed_s
 * @property {boolean} complete
 * @property {ImportReport} report
 * @property {PreviewChannel[]} channels
 * @property {number[]} t
 * @property {Record<string, Array<number | null>>} series
 * @property {"mcap" | "c3d" | null} mapping_kind
 * @property {string | null} mapping
 * @property {"given" | "saved" | "suggested" | null} mapping_source
 * @property {string | null} rig
 * @property {SourceField[]} fields
 * @property {string | null} problem
 */

const SVG_NS = "http://www.w3.org/2000/svg";
const SPARK_W = 160;
const SPARK_H = 36;
/** Radians to degrees: the scale of a field another tool records in rad (or rad/s). */
export const RAD_TO_DEG = 180 / Math.PI;

const SOURCE_WORDS = {
  given: "yours (edited here)",
  saved: "saved for this rig (the mapping its last import used)",
  suggested: "suggested by gaitscope (nothing saved for this rig yet)",
};

const FORMAT_WORDS = {
  mcap: "gaitscope MCAP recording",
  foreign_mcap: "MCAP recording of another tool",
  replay_csv: "replay CSV",
  locohub_csv: "LocoHub CSV",
  parquet: "LocoHub Parquet",
  c3d: "C3D motion capture",
};

const _svg = (tag, attrs) => {
  const el = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  return el;
};

/**
 * A sparkline of `ys` at times `t`: a line broken where a value is missing, scaled to its own range.
 * @param {number[]} t
 * @param {Array<number | null>} ys
 * @param {string} label
 */
export function sparkline(t, ys, label) {
  const svg = _svg("svg", { class: "spark", viewBox: `0 0 ${SPARK_W} ${SPARK_H}`, width: SPARK_W, height: SPARK_H,
    role: "img", "aria-label": label, "data-testid": "upload-preview-spark" });
  const pts = [];
  for (let i = 0; i < Math.min(t.length, ys.length); i++) {
    const y = ys[i];
    pts.push(y !== null && Number.isFinite(y) && Number.isFinite(t[i]) ? [t[i], Number(y)] : null);
  }
  const ok = pts.filter(Boolean);
  svg.setAttribute("data-points", String(ok.length));
  if (ok.length < 2) return svg;
  const [t0, t1] = [ok[0][0], ok[ok.length - 1][0]];
  let [lo, hi] = [Math.min(...ok.map((p) => p[1])), Math.max(...ok.map((p) => p[1]))];
  if (hi - lo < 1e-9) [lo, hi] = [lo - 1, hi + 1];
  const x = (v) => ((v - t0) / (t1 - t0 || 1)) * (SPARK_W - 2) + 1;
  const y = (v) => SPARK_H - 2 - ((v - lo) / (hi - lo)) * (SPARK_H - 4);
  let d = "";
  let pen = false;
  for (const p of pts) {
    if (!p) {
      pen = false;
      continue;
    }
    d += `${pen ? "L" : "M"}${x(p[0]).toFixed(1)} ${y(p[1]).toFixed(1)}`;
    pen = true;
  }
  svg.append(_svg("path", { d, fill: "none", stroke: "currentColor", "stroke-width": 1.2 }));
  return svg;
}

const range = (lo, hi, digits = 1) => (lo === null && hi === null ? "–" : `${fmt(lo, digits)} to ${fmt(hi, digits)}`);

/** One estimator's line: it runs on import, can run in a re-run, or cannot run and what it lacks. */
function feedItem(/** @type {EstimatorFeed} */ e) {
  const state = e.ran ? "runs" : e.feedable ? "rerun" : "cannot";
  const what = e.ran ? "runs on import" : e.feedable ? "can run in a re-run (opt-in)"
    : `cannot run: the file lacks ${listText(e.missing)}`;
  const derived = Object.entries(e.derived || {}).map(([input, by]) =>
    `${input} derived by ${listText(by.map(estimatorLabel))}`);
  return h("li", { class: `feed feed-${state}`, "data-testid": "upload-preview-feed", "data-estimator": e.name,
    "data-state": state },
  h("strong", { text: e.label }), `: ${what}`, derived.length ? ` (uses ${listText(derived)})` : "");
}

/**
 * What an import read or would read (ImportReport): the estimators it feeds, what it derives, ignores and warns of.
 * @param {ImportReport} report
 */
export function reportView(report) {
  const feeds = report.estimators || [];
  const can = feeds.filter((e) => e.feedable);
  const cannot = feeds.filter((e) => !e.feedable);
  // what cannot run is folded away while others can (the IMU front ends of a file with angles are noise there)
  const cannotList = h("ul", { class: "feeds" }, ...cannot.map(feedItem));
  return h("div", { class: "import-report", "data-testid": "upload-report" },
    h("p", {}, h("strong", { text: "Format: " }), FORMAT_WORDS[report.format] || report.format,
      `; channels: ${report.channels.length ? report.channels.join(", ") : "none"}`,
      report.derived.length ? `; computed from them: ${report.derived.join(", ")}` : ""),
    h("h3", { text: "Estimators it can feed" }),
    h("div", { "data-testid": "upload-preview-feeds" },
      h("ul", { class: "feeds" }, ...can.map(feedItem)),
      !can.length ? h("p", { class: "error", text: "None: the file feeds no estimator." }) : null,
      !cannot.length ? null : can.length
        ? h("details", {}, h("summary", { text: `${cannot.length} cannot run with this file: what each lacks` }), cannotList)
        : cannotList),
    report.ignored.length
      ? h("p", { class: "hint", "data-testid": "upload-preview-ignored" }, h("strong", { text: "Not read: " }),
        report.ignored.join(", "))
      : null,
    report.warnings.length
      ? h("ul", { class: "warnings", "data-testid": "upload-preview-warnings", "aria-label": "Warnings" },
        ...report.warnings.map((w) => h("li", { "data-testid": "upload-preview-warning", text: w })))
      : null);
}

/** The channels table: unit, source, range against the plausible one, values outside it, a sparkline. */
function channelsTable(/** @type {ImportPreview} */ p) {
  const plotted = p.previewed_s > 0 ? `First ${fmt(p.previewed_s, 0)} s` : "Plot";
  const rows = p.channels.map((c) => h("tr", { "data-testid": "upload-preview-channel", "data-channel": c.channel,
    class: c.outside > 0 ? "outside" : null },
  h("th", { scope: "row", text: c.channel }), h("td", { text: c.unit || "–" }),
  h("td", { class: "source", text: c.source }),
  h("td", { class: "num", "data-testid": "upload-preview-range", text: range(c.min, c.max) }),
  h("td", { class: "num", text: c.plausible ? range(c.plausible[0], c.plausible[1], 0) : "flag" }),
  h("td", { class: "num", "data-testid": "upload-preview-outside", text: c.outside ? `${c.outside} of ${c.count}` : "0" }),
  h("td", {}, sparkline(p.t, p.series[c.channel] || [], `${c.channel}: ${plotted.toLowerCase()}`))));
  return h("div", { class: "table-scroll" }, h("table", { class: "table preview-channels", "data-testid": "upload-preview-channels" },
    h("thead", {}, h("tr", {}, ...["Channel", "Unit", "From", "In the file", "Plausible", "Outside", plotted]
      .map((t) => h("th", { text: t })))),
    h("tbody", {}, rows.length ? rows : h("tr", {}, h("td", { colspan: 7, class: "empty", text: "No channel found." })))));
}

/** Every channel a field can be given: SENSOR_LIMITS' (wire.js), and any other the preview names (flags). */
function channelNames(/** @type {ImportPreview} */ p) {
  const names = new Set(Object.keys(SENSOR_LIMITS));
  for (const c of p.channels) names.add(c.channel);
  for (const f of p.fields) if (f.channel) names.add(f.channel);
  return [...names];
}

/** The mapping's JSON as an object, or null when it is missing or not JSON. */
function parsed(text) {
  try {
    const m = JSON.parse(text || "");
    return m && typeof m === "object" ? m : null;
  } catch {
    return null;
  }
}

/**
 * The preview panel. `show(preview)` draws an answer; `mappingText()` is the mapping edited here (throws a
 * ValidationError when it cannot be sent); the buttons are wired by upload.js.
 */
export class ImportPreviewPanel {
  /** @param {(detail: string) => string} problemText the server's reason in the user's terms (upload.js' refusalText) */
  constructor(problemText = (d) => d) {
    this.problemText = problemText;
    this.applyBtn = h("button", { type: "button", "data-testid": "upload-mapping-apply", text: "Apply mapping" });
    this.importBtn = h("button", { type: "button", class: "primary", "data-testid": "upload-import", text: "Import" });
    this.discardBtn = h("button", { type: "button", "data-testid": "upload-discard", text: "Discard" });
    this.otherRig = h("input", { type: "checkbox", "data-testid": "upload-allow-other-rig" });
    this.otherRig.addEventListener("change", () => this._changed());
    this.error = errorBox("upload-preview-error");
    this.importNote = h("p", { class: "hint", "data-testid": "upload-import-note" });
    this.body = h("div", { class: "preview-body" });
    this.el = h("section", { class: "upload-preview", "data-testid": "upload-preview", hidden: true, "aria-label": "Import preview" },
      this.body, this.error, h("div", { class: "buttons" }, this.importBtn, this.discardBtn), this.importNote);
    /** @type {ImportPreview | null} */
    this.preview = null;
    /** @type {() => string} */
    this._read = () => null;
    this.dirty = false;
  }

  /** Hides the panel and forgets the preview. */
  clear() {
    this.preview = null;
    this.dirty = false;
    this.otherRig.checked = false;
    showError(this.error, null);
    this.body.replaceChildren();
    this.el.hidden = true;
  }

  /** @param {ImportPreview} p */
  show(p) {
    this.preview = p;
    this.dirty = false;
    const editor = p.mapping_kind === "mcap" ? this._mcapEditor(p) : p.mapping_kind === "c3d" ? this._c3dEditor(p) : null;
    this.body.replaceChildren(...[
      h("h3", { text: `Preview of ${p.filename}` }),
      h("p", { class: "hint", "data-testid": "upload-preview-summary" },
        `${FORMAT_WORDS[p.format] || p.format}; ${p.complete ? "the whole file read"
          : p.previewed_s > 0 ? `its first ${fmt(p.previewed_s, 0)} s read` : "no channel could be read"}. `
        + "Nothing is stored until you import it."),
      p.problem ? h("p", { class: "error upload-problem", role: "alert", "data-testid": "upload-preview-problem",
        text: `It cannot be imported as it is: ${this.problemText(p.problem)}` }) : null,
      channelsTable(p), reportView(p.report), editor].filter(Boolean));
    this.el.hidden = false;
    this.refresh();
  }

  /** The Import button: disabled while there is a problem or an edited mapping not previewed yet. */
  refresh() {
    const p = this.preview;
    const fix = p && p.mapping_kind ? " (change the mapping and apply it)" : "";
    const why = !p ? "" : p.problem ? `Import is off until the problem above is solved${fix}.`
      : this.dirty ? "The mapping was edited: apply it to preview it before importing." : "";
    this.importBtn.disabled = !p || Boolean(why);
    this.importNote.textContent = why;
  }

  /** The mapping to send (JSON text): what is edited here, or the one in use when the file needs none. */
  mappingText() {
    return this._read();
  }

  /** The options of the next preview or of the import: the mapping in use (the one previewed). */
  options() {
    const p = this.preview;
    return { mapping: p ? p.mapping : null, allow_other_rig: this.otherRig.checked };
  }

  _source(p) {
    const rig = p.rig ? ` (rig ${p.rig})` : "";
    return h("p", { "data-testid": "upload-mapping-source", "data-source": p.mapping_source || "" },
      h("strong", { text: "Channel mapping: " }), `${SOURCE_WORDS[p.mapping_source] || "none"}${rig}.`);
  }

  _changed() {
    this.dirty = true;
    this.refresh();
  }

  _otherRigField() {
    return h("label", { class: "choice" }, this.otherRig,
      h("span", { text: "Use the mapping although it was made for another rig (check that it still fits)" }));
  }

  /** Another tool's MCAP recording: a channel and a scale per field, built into a ChannelMapping's JSON. */
  _mcapEditor(/** @type {ImportPreview} */ p) {
    const current = parsed(p.mapping) || {};
    const entries = Array.isArray(current.entries) ? current.entries : [];
    const names = channelNames(p);
    const rows = p.fields.map((f) => {
      const entry = entries.find((e) => e.topic === f.topic && e.field === f.path);
      const select = h("select", { "data-testid": "upload-mapping-channel", "aria-label": `Channel of ${f.topic} ${f.path}` },
        h("option", { value: "", text: "none" }), ...names.map((n) => h("option", { value: n, text: n })));
      select.value = f.channel || "";
      const scale = h("input", { type: "number", step: "any", class: "scale", "data-testid": "upload-mapping-scale",
        "aria-label": `Scale of ${f.topic} ${f.path}`, value: String(entry ? entry.scale : 1), disabled: f.kind === "bool" });
      select.addEventListener("change", () => this._changed());
      scale.addEventListener("input", () => this._changed());
      const tr = h("tr", { "data-testid": "upload-mapping-field", "data-topic": f.topic, "data-path": f.path },
        h("td", { text: f.topic }), h("td", { text: f.path }), h("td", { text: f.kind }),
        h("td", { class: "num", text: f.rate_hz ? `${fmt(f.rate_hz, 1)} Hz` : "–" }),
        h("td", { class: "num", text: range(f.min, f.max, 3) }), h("td", {}, select), h("td", {}, scale));
      return { f, select, scale, offset: entry ? Number(entry.offset) || 0 : 0, tr };
    });
    this._read = () => {
      const used = new Map();
      const chosen = [];
      for (const r of rows) {
        const channel = r.select.value;
        if (!channel) continue;
        if (used.has(channel)) {
          throw new ValidationError(`${channel} is chosen for two fields (${used.get(channel)} and ${r.f.topic} ${r.f.path}): choose it once.`);
        }
        used.set(channel, `${r.f.topic} ${r.f.path}`);
        const scale = r.scale.value.trim() === "" ? 1 : Number(r.scale.value);
        if (!Number.isFinite(scale) || scale === 0) {
          throw new ValidationError(`The scale of ${r.f.topic} ${r.f.path} must be a number other than 0.`);
        }
        chosen.push({ topic: r.f.topic, field: r.f.path, channel, scale: r.f.kind === "bool" ? 1 : scale,
          offset: r.f.kind === "bool" ? 0 : r.offset });
      }
      if (!chosen.length) throw new ValidationError("Choose a channel for at least one field.");
      return JSON.stringify({ version: 1, rig: typeof current.rig === "string" ? current.rig : "",
        time_source: current.time_source || "log_time", entries: chosen });
    };
    return h("div", { class: "mapping-editor", "data-testid": "upload-mapping" },
      h("h3", { text: "The file's fields" }), this._source(p),
      h("p", { class: "hint", text: "Give each field the gaitscope channel it holds, and the scale that turns its values into the "
        + `channel's unit (${RAD_TO_DEG} turns radians into degrees). Fields left at "none" are not read.` }),
      h("div", { class: "table-scroll" }, h("table", { class: "table mapping-fields" },
        h("thead", {}, h("tr", {}, ...["Topic", "Field", "Kind", "Rate", "Range", "Channel", "Scale"].map((t) => h("th", { text: t })))),
        h("tbody", {}, ...rows.map((r) => r.tr)))),
      this._otherRigField(),
      h("div", { class: "buttons" }, this.applyBtn),
      h("details", {}, h("summary", { text: "The mapping in use, as JSON" }),
        h("pre", { class: "mapping-json", "data-testid": "upload-mapping-json", text: p.mapping || "" })));
  }

  /** A C3D file: the markers found and their roles; the mapping (marker set) as editable JSON. */
  _c3dEditor(/** @type {ImportPreview} */ p) {
    const pretty = parsed(p.mapping);
    const text = h("textarea", { class: "mapping-text", rows: 12, spellcheck: "false", "data-testid": "upload-mapping-text",
      "aria-label": "The C3D mapping (JSON)" });
    text.value = pretty ? JSON.stringify(pretty, null, 2) : p.mapping || "";
    text.addEventListener("input", () => this._changed());
    this._read = () => {
      if (parsed(text.value) === null) throw new ValidationError("The mapping is not valid JSON.");
      return text.value;
    };
    // markers come without a rate or range: those columns only when a field has them (analog channels)
    const table = (fields) => {
      const more = fields.some((f) => f.rate_hz || f.min !== null || f.max !== null);
      return h("div", { class: "table-scroll" }, h("table", { class: "table mapping-fields" },
        h("thead", {}, h("tr", {}, ...["Kind", "Label", "Role", ...(more ? ["Rate", "Range"] : [])].map((t) => h("th", { text: t })))),
        h("tbody", {}, ...fields.map((f) => h("tr", { "data-testid": "upload-mapping-field", "data-topic": f.topic, "data-path": f.path },
          h("td", { text: f.topic }), h("td", { text: f.path }), h("td", { "data-testid": "upload-mapping-role", text: f.channel || "not used" }),
          more ? h("td", { class: "num", text: f.rate_hz ? `${fmt(f.rate_hz, 0)} Hz` : "–" }) : null,
          more ? h("td", { class: "num", text: range(f.min, f.max, 1) }) : null)))));
    };
    const used = p.fields.filter((f) => f.channel);
    const unused = p.fields.filter((f) => !f.channel);
    return h("div", { class: "mapping-editor", "data-testid": "upload-mapping" },
      h("h3", { text: "Markers and analog channels found" }), this._source(p),
      used.length ? table(used) : h("p", { class: "error", text: "No marker or analog channel has a role in this mapping." }),
      unused.length ? h("details", {}, h("summary", { text: `${unused.length} more, not used by the mapping` }), table(unused)) : null,
      h("label", { class: "field" }, h("span", { class: "caption", text: "Mapping (JSON): each role's marker label, the analog channels" }), text),
      this._otherRigField(),
      h("div", { class: "buttons" }, this.applyBtn));
  }
}
