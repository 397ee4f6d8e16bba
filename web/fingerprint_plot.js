// The subject page's "where the subject sits" plot (web/subject.js): the fingerprints g1 against g2 of the
// model's training subjects, the subject's versions and the live online fingerprint, as one small SVG
// (a few dozen elements, redrawn whole), and a fingerprint as text.

import { fmt } from "./ui.js";

const SVG_NS = "http://www.w3.org/2000/svg";

const plural = (n, word) => `${n} ${word}${n === 1 ? "" : "s"}`;

/** A fingerprint as text: "g1 0.12 · g2 -1.30 · …" (degrees). */
export const gText = (g) => g.map((x, i) => `g${i + 1} ${fmt(x, 2)}`).join(" · ");

/** An SVG element (`h` builds HTML ones). */
function svg(tag, attrs = {}, ...children) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== null && v !== undefined) el.setAttribute(k, String(v));
  for (const c of children.flat(Infinity)) if (c !== null && c !== undefined) el.append(c);
  return el;
}

/** About `n` round tick values covering [lo, hi]. */
function ticks(lo, hi, n = 5) {
  const raw = (hi - lo) / n;
  const mag = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.round(v / step) * step);
  return out;
}

/**
 * "Where the subject sits": g1 against g2 of the training subjects (labelled), the subject's versions (the
 * active one ringed) and the live online fingerprint. Redrawn whole: a few dozen elements.
 * @param {object} fps the subject's `GET /api/subjects/{id}/fingerprints` (cohort, versions, active)
 * @param {string} code the subject's code, for the labels
 * @param {{g?: number[]} | null} live the online fingerprint of a running session (drawn when it has `g`)
 * @returns {SVGSVGElement}
 */
export function fingerprintScatter(fps, code, live) {
  const W = 520;
  const H = 380;
  const M = { l: 56, r: 20, t: 16, b: 50 };
  const g12 = (f) => [f[0] ?? 0, f[1] ?? 0];
  const pts = [
    ...fps.cohort.map((c) => ({ kind: "cohort", label: c.code, g: g12(c.fingerprint) })),
    ...fps.versions.map((v) => ({ kind: v.state, label: `v${v.version}`, g: g12(v.fingerprint), v })),
    ...(live && live.g ? [{ kind: "live", label: "live", g: g12(live.g) }] : []),
  ];
  const span = (i) => {
    const xs = pts.map((p) => p.g[i]);
    const [lo, hi] = [Math.min(0, ...xs), Math.max(0, ...xs)];
    const pad = Math.max((hi - lo) * 0.1, 0.5);
    return [lo - pad, hi + pad];
  };
  const [x0, x1] = span(0);
  const [y0, y1] = span(1);
  const tickText = (v) => fmt(v, Number.isInteger(v) ? 0 : 1);
  const X = (x) => M.l + ((x - x0) / (x1 - x0)) * (W - M.l - M.r);
  const Y = (y) => H - M.b - ((y - y0) / (y1 - y0)) * (H - M.t - M.b);
  const grid = [
    ...ticks(x0, x1).map((v) => [svg("line", { x1: X(v), x2: X(v), y1: M.t, y2: H - M.b, class: v === 0 ? "axis-zero" : "grid" }),
      svg("text", { x: X(v), y: H - M.b + 18, "text-anchor": "middle", class: "tick" }, tickText(v))]),
    ...ticks(y0, y1).map((v) => [svg("line", { x1: M.l, x2: W - M.r, y1: Y(v), y2: Y(v), class: v === 0 ? "axis-zero" : "grid" }),
      svg("text", { x: M.l - 8, y: Y(v) + 5, "text-anchor": "end", class: "tick" }, tickText(v))]),
    svg("text", { x: (M.l + W - M.r) / 2, y: H - 8, "text-anchor": "middle", class: "axis-label" }, "g1 (deg)"),
    svg("text", { x: 16, y: (M.t + H - M.b) / 2, "text-anchor": "middle", class: "axis-label",
      transform: `rotate(-90 16 ${(M.t + H - M.b) / 2})` }, "g2 (deg)"),
  ];
  // The cohort's labels right of their dots, the subject's left of theirs (a version sits near its training
  // subject); a label overlapping one already placed moves down a line, so versions at one spot stay readable.
  const placed = [];
  const labelAt = (right, x, y, text) => {
    const w = 7.5 * text.length;
    const [a, b] = right ? [x, x + w] : [x - w, x];
    while (placed.some((q) => a < q.b && q.a < b && Math.abs(q.y - y) < 14)) y += 15;
    placed.push({ a, b, y });
    return svg("text", { x, y, "text-anchor": right ? "start" : "end", class: "pt-label" }, text);
  };
  const mark = (p) => {
    const [cx, cy] = [X(p.g[0]), Y(p.g[1])];
    const title = svg("title", {}, p.kind === "cohort" ? `training subject ${p.label}: ${gText(p.g)}`
      : p.kind === "live" ? `live online fingerprint: ${gText(live.g)}` : `${code} ${p.label} (${p.kind}): ${gText(p.v.fingerprint)}`);
    const attrs = p.kind === "cohort" ? { "data-testid": "fp-point-cohort", "data-code": p.label }
      : p.kind === "live" ? { "data-testid": "fp-point-live", "data-g1": p.g[0], "data-g2": p.g[1] }
        : { "data-testid": "fp-point-version", "data-version": p.v.version, "data-state": p.kind };
    const r = { cohort: 5, retired: 6, candidate: 7, active: 9, live: 8 }[p.kind];
    const label = p.kind === "active" ? `${p.label} active` : p.label;
    return svg("g", { class: `pt pt-${p.kind}`, ...attrs }, title,
      p.kind === "active" || p.kind === "live" ? svg("circle", { cx, cy, r: r + 5, class: "halo" }) : null,
      svg("circle", { cx, cy, r }), p.kind === "cohort" || p.kind === "live"
        ? labelAt(true, cx + r + 4, cy + 5, label) : labelAt(false, cx - r - 4, cy + 5, label));
  };
  const active = fps.active;
  const summary = `Fingerprints g1 against g2: ${plural(fps.cohort.length, "training subject")}, `
    + `${plural(fps.versions.length, `version`)} of ${code}${active ? ` (v${active.version} active at ${gText(active.fingerprint.slice(0, 2))})` : ""}`
    + `${live && live.g ? `, live online fingerprint at ${gText(live.g.slice(0, 2))}` : ""}.`;
  // labels placed active first (it keeps its place), marks drawn active last (on top)
  const rank = { active: 0, live: 1, candidate: 2, retired: 3 };
  const own = pts.filter((p) => p.kind !== "cohort").sort((a, b) => rank[a.kind] - rank[b.kind]).map(mark);
  return svg("svg", { viewBox: `0 0 ${W} ${H}`, role: "img", "aria-label": summary, "data-testid": "fp-scatter", class: "fp-svg" },
    grid, pts.filter((p) => p.kind === "cohort").map(mark), own.reverse());
}
