// The y range of every signal the dashboard plots, in one table, and the user's own ranges (localStorage).
// Ranges are physiological: a plot never auto-scales to a quarter of a degree of noise. Signals with a `fit` (issue
// #23: incline, phase rate, stride length, speed) fit their data, never narrower than `fit` (a physiological span),
// and show `range` until there are data; the others (phase, torque with the session's bound, angles) stay fixed.

/**
 * Per signal (a plot spec's `yKey`, else its `key`): the y range shown by default, and the unit of its
 * hover values. `range` is [min, max] or `(ctx) => [min, max]` with `ctx` the plot's context (for the torque,
 * `ctx.max_torque_Nm`, the session's hard bound on the command). The angles hold a simulated walk's extremes
 * at 0.8-1.6 m/s on -10 to +10 deg (sessions/synth: foot -73 to 34 deg, shank -78 to 45, thigh -32 to 36,
 * knee -6 to 72, hip -21 to 49, ankle -12 to 19) with a margin.
 */
export const Y_RANGES = {
  phase: { range: [0, 100], unit: "%", name: "gait phase" },
  stance: { range: [0, 100], unit: "%", name: "stance phase" },
  phase_rate: { range: [0, 2], fit: 0.4, unit: "1/s", name: "phase rate" },
  incline: { range: [-15, 15], fit: 4, unit: "deg", name: "incline" },
  stride_length: { range: [0, 2], fit: 0.4, unit: "m", name: "stride length" },
  stride: { range: [0, 2], fit: 0.4, unit: "m", name: "stride length" },
  torque: { range: (ctx) => [0, 1.05 * (ctx.max_torque_Nm ?? 30)], unit: "N·m", name: "torque" },
  foot: { range: [-80, 40], unit: "deg", name: "foot angle" },
  shank: { range: [-80, 50], unit: "deg", name: "shank angle" },
  joints: { range: [-40, 80], unit: "deg", name: "hip and knee flexion" },
  thigh: { range: [-40, 50], unit: "deg", name: "thigh angle" },
  hip: { range: [-30, 50], unit: "deg", name: "hip angle" },
  knee: { range: [-10, 80], unit: "deg", name: "knee angle" },
  ankle: { range: [-30, 30], unit: "deg", name: "ankle angle" },
  intent: { range: [0, 2.5], fit: 0.5, unit: "m/s", name: "walking speed" },
  speed: { range: [0, 2.5], fit: 0.5, unit: "m/s", name: "walking speed" },
};

/** Units of hover values from a y-axis label when the table has none ("% of cycle" -> "%"). */
export function unitOf(yLabel) {
  if (!yLabel) return "";
  if (yLabel.startsWith("%")) return "%";
  return yLabel;
}

const _STORE = "gaitscope.plots.y.";

/** The user's range for a signal, or null (none stored, or unreadable: dropped). */
export function storedRange(key) {
  try {
    const v = JSON.parse(localStorage.getItem(_STORE + key) || "null");
    return Array.isArray(v) && v.length === 2 && v.every(Number.isFinite) && v[0] < v[1] ? v : null;
  } catch {
    return null;
  }
}

/** Remembers (or with null forgets) the user's range for a signal. */
export function storeRange(key, range) {
  if (range) localStorage.setItem(_STORE + key, JSON.stringify(range));
  else localStorage.removeItem(_STORE + key);
}

/**
 * The default range of a signal: `spec.yRange` if given, else the table's, else null (auto).
 * @returns {number[] | Function | null}
 */
export function defaultRange(key, specRange, ctx) {
  if (specRange) return specRange;
  const entry = Y_RANGES[key];
  if (!entry) return null;
  return typeof entry.range === "function" ? entry.range(ctx || {}) : entry.range;
}

/**
 * The range fitted to data from `min` to `max` for a signal with a `fit` span: 5 % margin, ends rounded out to a
 * tenth of the span; or, for data within less, the span about their middle (rounded to a tenth of it); null for a signal without one or without data.
 * @param {string | null} key @param {number | null | undefined} min @param {number | null | undefined} max
 * @returns {[number, number] | null}
 */
export function fitRange(key, min, max) {
  const entry = key ? Y_RANGES[key] : null;
  if (!entry || !entry.fit || min == null || max == null || !Number.isFinite(min) || !Number.isFinite(max)) return null;
  const span = entry.fit;
  const step = span / 10;
  const round = (v) => Math.round(v * 1e6) / 1e6; // no 0.30000000000000004 on the axis
  const pad = 0.05 * (max - min);
  if (max - min + 2 * pad < span) {
    const c = Math.round((min + max) / 2 / step) * step; // the span about the data's middle, rounded to a step
    return [round(c - span / 2), round(c + span / 2)];
  }
  return [round(Math.floor((min - pad) / step) * step), round(Math.ceil((max + pad) / step) * step)];
}

/**
 * Reads the min and max a user typed for a y range; throws an Error in plain words when they are not a
 * range (not numbers, or min not below max).
 */
export function parseRange(minText, maxText) {
  const lo = Number(String(minText).trim());
  const hi = Number(String(maxText).trim());
  if (String(minText).trim() === "" || !Number.isFinite(lo)) throw new Error("The lowest value must be a number.");
  if (String(maxText).trim() === "" || !Number.isFinite(hi)) throw new Error("The highest value must be a number.");
  if (!(lo < hi)) throw new Error("The lowest value must be below the highest.");
  return [lo, hi];
}
