// The live page's data-health verdict: ok, amber or red from the latency, the drop rates and the sample rate,
// against limits stated once here (and shown in the health box's help), whatever the socket's state. "LIVE"
// is said only when data is flowing and every figure is within its limits.

/** The limits: a figure at or over `amber` turns the box amber, at or over `red` red. */
export const HEALTH_LIMITS = Object.freeze({
  latencyMs: Object.freeze({ amber: 200, red: 1000, what: "Device → screen delay (95th percentile)", unit: "ms" }),
  inputDropPct: Object.freeze({ amber: 1, red: 5, what: "Device frames lost (last 5 s)", unit: "%" }),
  clientDrops: Object.freeze({ amber: 1, red: 100, what: "Samples this screen missed (last 5 s)", unit: "samples" }),
  rateShortPct: Object.freeze({ amber: 10, red: 50, what: "Sample rate below the device's declared rate", unit: "%" }),
});
/** No data for this long (ms) and the stream is stale: red. */
export const STALE_MS = 1000;
/** Seconds over which the drop rates are counted. */
export const DROP_WINDOW_S = 5;

/** The help text of the health box: every limit in plain words. */
export function limitsHelp() {
  const lines = Object.values(HEALTH_LIMITS).map((l) => `${l.what}: amber from ${l.amber} ${l.unit}, red from ${l.red} ${l.unit}.`);
  return [`The box is green and says LIVE only while data arrives (at least every ${STALE_MS / 1000} s) and every figure is within its limits.`,
    ...lines, "Red also when the connection to the server is lost, whatever the figures."];
}

/**
 * Counts of the last `DROP_WINDOW_S` seconds from the health messages' running totals.
 */
export class DropWindow {
  constructor() {
    this.points = []; // [ms, samples, dropped_input, dropped_client]
  }

  /** A health message's totals at `nowMs`; returns {inputDropPct, clientDrops} over the window. */
  add(nowMs, m) {
    this.points.push([nowMs, m.samples, m.dropped_input, m.dropped_client]);
    while (this.points.length > 1 && nowMs - this.points[0][0] > DROP_WINDOW_S * 1000) this.points.shift();
    const [, s0, i0, c0] = this.points[0];
    const samples = Math.max(0, m.samples - s0);
    const lost = Math.max(0, m.dropped_input - i0);
    return {
      inputDropPct: samples + lost > 0 ? (100 * lost) / (samples + lost) : 0,
      clientDrops: Math.max(0, m.dropped_client - c0),
    };
  }

  clear() {
    this.points = [];
  }
}

const _RANK = { ok: 0, amber: 1, red: 2 };

/**
 * The verdict on the figures.
 * @param {{connected: boolean, flowing: boolean, latencyMs: number | null, inputDropPct: number,
 *   clientDrops: number, rateHz: number | null, declaredHz: number | null, ended?: boolean}} f
 *   `ended`: the session is no longer running (its last figures are kept, and judged no more)
 * @returns {{level: "ok" | "amber" | "red", live: boolean, reasons: string[]}}
 */
export function judgeHealth(f) {
  /** @type {"ok" | "amber" | "red"} */
  let level = "ok";
  const reasons = [];
  const raise = (to, why) => {
    if (_RANK[to] > _RANK[level]) level = to;
    reasons.push(why);
  };
  if (f.ended) return { level: "red", live: false, reasons: ["The session is not running: no data comes."] };
  if (!f.connected) raise("red", "No connection to the server.");
  else if (!f.flowing) raise("red", `No data for over ${STALE_MS / 1000} s.`);
  const check = (key, value, shown) => {
    if (value == null || !Number.isFinite(value)) return;
    const l = HEALTH_LIMITS[key];
    if (value >= l.red) raise("red", `${l.what}: ${shown} ${l.unit}, over the red limit of ${l.red} ${l.unit}.`);
    else if (value >= l.amber) raise("amber", `${l.what}: ${shown} ${l.unit}, over the amber limit of ${l.amber} ${l.unit}.`);
  };
  check("latencyMs", f.latencyMs, f.latencyMs == null ? "" : f.latencyMs.toFixed(0));
  check("inputDropPct", f.inputDropPct, f.inputDropPct.toFixed(1));
  check("clientDrops", f.clientDrops, String(f.clientDrops));
  if (f.flowing && f.declaredHz && f.rateHz != null) {
    const short = Math.max(0, 100 * (1 - f.rateHz / f.declaredHz));
    check("rateShortPct", short, short.toFixed(0));
  }
  return { level, live: level === "ok" && f.connected && f.flowing, reasons };
}
