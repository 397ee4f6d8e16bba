// The live page's data-health box: the session's figures, the verdict (green / amber / red, `live_health.js`)
// with the reasons in plain words, the limits in its help, and the LIVE indicator, which says LIVE only while
// data flows within those limits.

import { DropWindow, HEALTH_LIMITS, judgeHealth, limitsHelp, STALE_MS } from "./live_health.js";
import { fmt, h } from "./ui.js";

const INDICATOR = { ok: "LIVE", amber: "CHECK DATA", red: "NOT LIVE" };

export class HealthBox {
  constructor() {
    const dd = (key) => h("dd", { "data-testid": `health-${key}`, text: "–" });
    this.f = { t: dd("session-time"), rate: dd("rate"), latency: dd("latency"), serverLatency: dd("server-latency"),
      input: dd("dropped-input"), client: dd("dropped-client"), clients: dd("clients"), samples: dd("samples"),
      implausible: dd("implausible"), faults: dd("faults"), disk: dd("disk"), primary: dd("primary"),
      failedEstimators: dd("failed-estimators"), tracking: dd("tracking"), imu: dd("imu") };
    const f = this.f;
    this.indicator = h("div", { class: "indicator stale", "data-testid": "live-indicator", role: "status", text: "NO DATA" });
    this.reasons = h("ul", { class: "health-reasons", "data-testid": "health-reasons", "aria-live": "polite" });
    this.conn = h("span", { class: "hint", "data-testid": "connection", text: "connecting…" });
    const help = h("details", { class: "health-help", "data-testid": "health-help" }, h("summary", { text: "When is it amber or red?" }),
      h("ul", {}, ...limitsHelp().map((line) => h("li", { text: line }))));
    const row = (label, el) => [h("dt", { text: label }), el];
    this.el = h("section", { class: "card health", "data-testid": "health", "data-level": "red" },
      h("div", { class: "card-head" }, h("h2", { text: "Data health" }), this.indicator), this.reasons,
      h("dl", {}, ...row("Session time", f.t), ...row("Rate", f.rate), ...row("Device → screen latency p50 / p95", f.latency),
        ...row("Device → server p50 / p95", f.serverLatency), ...row("Dropped device frames", f.input),
        ...row("Dropped batches (this screen)", f.client), ...row("Screens connected", f.clients), ...row("Samples", f.samples),
        ...row("Implausible sensor values (ignored)", f.implausible), ...row("Estimator resets / torque faults", f.faults),
        ...row("Recording disk", f.disk), ...row("Torque follows (primary estimator)", f.primary),
        ...row("Failed estimators", f.failedEstimators), ...row("Gait tracking", f.tracking), ...row("IMUs", f.imu)),
      help, this.conn);
    this.recent = []; // [arrival ms, device → screen ms] of the last second
    this.drops = new DropWindow();
    this.window = { inputDropPct: 0, clientDrops: 0 };
    this.last = null; // the last health message
    this.lastBatchAt = 0;
    this.connected = false;
    this.declaredHz = null;
    this.ended = false; // the session is no longer running
    this.verdict = null;
  }

  /** Live states arrived (not the history sent on connecting: it says nothing about now). */
  noteStates(states, now = performance.now()) {
    const wall = Date.now();
    for (const s of states) if (s.sent_ns != null) this.recent.push([wall, wall - s.sent_ns / 1e6]);
    while (this.recent.length && wall - this.recent[0][0] > 1000) this.recent.shift();
    if (states.length) this.lastBatchAt = now;
  }

  /** Device → screen latency quantile `p` (ms) over the last second, or null. */
  latency(p) {
    if (!this.recent.length) return null;
    const v = this.recent.map((x) => x[1]).sort((a, b) => a - b);
    return v[Math.min(v.length - 1, Math.floor(p * v.length))];
  }

  /** The socket's state in words, and whether it is open. */
  setConnection(text, connected) {
    this.conn.textContent = text;
    this.connected = connected;
    if (!connected) {
      this.drops.clear();
      this.recent = [];
    }
  }

  onHealth(m) {
    const f = this.f;
    this.last = m;
    this.window = this.drops.add(performance.now(), m);
    f.rate.textContent = `${fmt(m.rate_hz, 0)} Hz`;
    f.serverLatency.textContent = `${fmt(m.latency_ms_p50, 1)} / ${fmt(m.latency_ms_p95, 1)} ms`;
    f.input.textContent = `${m.dropped_input} (${fmt(this.window.inputDropPct, 1)} % in the last 5 s)`;
    f.client.textContent = String(m.dropped_client);
    f.clients.textContent = String(m.clients);
    f.samples.textContent = String(m.samples);
    f.client.classList.toggle("warn", this.window.clientDrops > 0);
    f.input.classList.toggle("warn", this.window.inputDropPct >= HEALTH_LIMITS.inputDropPct.amber);
    f.implausible.textContent = String(m.implausible ?? 0);
    f.implausible.classList.toggle("warn", (m.implausible ?? 0) > 0);
    f.faults.textContent = String(m.faults ?? 0);
    f.faults.classList.toggle("warn", (m.faults ?? 0) > 0);
    const left = m.disk_minutes == null ? "" : `about ${Math.round(m.disk_minutes)} min of recording left`;
    f.disk.textContent = { ok: left ? `ok: ${left}` : "ok",
      low: `space low: ${left ? left + ", then " : ""}recording stops`, critical: "full: recording stopped" }[m.disk ?? "ok"];
    f.disk.classList.toggle("warn", (m.disk ?? "ok") !== "ok");
    f.tracking.textContent = { walking: "walking", standing: "standing still: phase held, torque 0",
      lost: `lost track, reset: ${m.tracking_note || ""}` }[m.tracking] || "–";
    f.tracking.classList.toggle("warn", m.tracking === "lost");
    f.imu.textContent = { ok: "ok", fault: m.imu_note }[m.imu] || "–";
    f.imu.classList.toggle("warn", m.imu === "fault");
  }

  /** Verdict and indicator (a few times a second); returns the verdict. */
  update(now = performance.now(), sessionT = NaN) {
    const f = this.f;
    const p95 = this.latency(0.95);
    f.latency.textContent = p95 == null ? "–" : `${fmt(this.latency(0.5), 1)} / ${fmt(p95, 1)} ms`;
    f.t.textContent = `${fmt(sessionT, 1)} s`;
    const flowing = this.lastBatchAt > 0 && now - this.lastBatchAt <= STALE_MS;
    const m = this.last;
    const latencyMs = p95 ?? (m ? m.latency_ms_p95 : null);
    const v = judgeHealth({ connected: this.connected, flowing, latencyMs, inputDropPct: this.window.inputDropPct,
      clientDrops: this.window.clientDrops, rateHz: m ? m.rate_hz : null, declaredHz: this.declaredHz, ended: this.ended });
    f.latency.classList.toggle("warn", latencyMs != null && latencyMs >= HEALTH_LIMITS.latencyMs.amber);
    const text = this.lastBatchAt === 0 && this.connected ? "NO DATA" : INDICATOR[v.level];
    if (this.indicator.textContent !== text) this.indicator.textContent = text;
    this.indicator.className = `indicator ${v.live ? "live" : v.level === "amber" ? "amber" : "stale"}`;
    this.el.dataset.level = v.level;
    const key = v.reasons.join("\n");
    if (!this.verdict || key !== this.verdict.reasons.join("\n")) {
      this.reasons.replaceChildren(...v.reasons.map((r) => h("li", { text: r })));
    }
    this.verdict = v;
    return v;
  }
}
