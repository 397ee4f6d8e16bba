// Session summary (`#/sessions/{id}/summary`): what a session gave once it stopped (or so far, while it runs):
// duration, strides, speed and incline profile, per-condition stride curves, settings history, data health and
// events, from `GET /api/sessions/{id}/summary`; and the exports (report_export.js). Issue #23: the duration is the
// time recorded, beside the session's wall time; the conditions are those held (summary.py says the rule); the
// profile's line breaks at gaps; the page shows how far the server has got while it reads the recordings (a long
// session takes seconds), and the server keeps the summary until the session's trials change.

import { ApiError } from "./api.js";
import * as api from "./api_client.js";
import { estimatorLabel } from "./estimators.js";
import { EventList } from "./events.js";
import { fmtDuration, plural, STATE_WORDS } from "./people_format.js";
import { COLORS, Plot } from "./plots.js";
import { exportCard } from "./report_export.js";
import { errorBox, field, fmt, fmtUtc, h, showError } from "./ui.js";
import { SETTING_NAMES } from "./wire.js";

const SIGNALS = {
  torque_Nm: { label: "Assistance torque", unit: "N·m" },
  thigh_angle_deg: { label: "Thigh angle", unit: "deg" },
  shank_angle_deg: { label: "Shank angle", unit: "deg" },
  foot_angle_deg: { label: "Foot angle", unit: "deg" },
};
const STRIDE_GREY = "#9ca3af";

const PROGRESS_MS = 300;

/** `[t, y]` of a profile's value with a gap (null) before each stride after time not recorded (`after_gap`). */
export function profileLine(profile, value) {
  const t = [];
  const y = [];
  profile.forEach((p, k) => {
    if (k && p.after_gap) {
      t.push((profile[k - 1].t + p.t) / 2);
      y.push(null);
    }
    t.push(p.t);
    y.push(p[value]);
  });
  return [t, y];
}

const duration = (s) => (s < 60 ? `${fmt(s, 1)} s` : `${fmtDuration(s)} (${fmt(s, 1)} s)`);

const dl = (rows) => h("dl", { class: "people-figures" },
  ...rows.flatMap(([dt, dd, testid]) => [h("dt", { text: dt }), h("dd", { "data-testid": testid, text: dd })]));

export function mountReport(root, sessionId) {
  const st = { alive: true, plots: [], summary: null };
  const title = h("h1", { "data-testid": "report-title", text: `Session ${sessionId}: summary` });
  const note = h("p", { class: "hint", "data-testid": "report-note", text: "Reading the session's recordings…" });
  const error = errorBox("report-error");
  const body = h("div", { class: "people-report", "aria-busy": "true" });
  const exports = exportCard(sessionId);
  root.append(h("div", { class: "page report-page" }, title, note, error, body));

  function plot(container, spec) {
    const p = new Plot(container, spec);
    st.plots.push(p);
    return p;
  }

  function walking(s) {
    return h("section", { class: "card", "data-testid": "report-walking" }, h("h2", { text: "Walking" }), dl([
      [`Recorded time (${plural(s.trials.length, "trial")})`, duration(s.duration_s), "report-duration"],
      ["Wall time, start to stop", s.wall_s === null ? "still running" : duration(s.wall_s), "report-wall"],
      ["Strides", String(s.strides), "report-strides"],
      ["Mean speed", s.mean_speed_m_s === null ? "–" : `${fmt(s.mean_speed_m_s, 2)} m/s`, "report-speed"],
      ["Mean stride length", s.mean_stride_length_m === null ? "–" : `${fmt(s.mean_stride_length_m, 2)} m`, "report-stride-length"],
      ["Cadence", s.mean_cadence_spm === null ? "–" : `${fmt(s.mean_cadence_spm, 1)} strides per minute`, "report-cadence"],
      ["Started", fmtUtc(s.started_utc), "report-started"],
      ["Stopped", s.stopped_utc ? fmtUtc(s.stopped_utc) : "still running", "report-stopped"],
      ["Trials", s.trials.map((t) => `${t.name} (${fmt(t.duration_s, 1)} s)`).join(", ") || "none recorded", "report-trials"],
    ]));
  }

  function health(s) {
    const x = s.health;
    return h("section", { class: "card", "data-testid": "report-health" }, h("h2", { text: "Data health" }), dl([
      ["Samples", `${x.samples} over ${fmt(x.recorded_s, 1)} s recorded`, "health-samples"],
      ["Sample rate", x.rate_hz === null ? "–" : `${fmt(x.rate_hz, 1)} Hz`, "health-rate"],
      ["Gaps in the data", `${x.gaps}${x.gaps ? ` (longest ${fmt(x.longest_gap_s, 2)} s)` : ""}`, "health-gaps"],
      ["Samples missing a joint angle", `${fmt(x.missing_percent, 2)} %`, "health-missing"],
      ["Filter resets and torque cut to zero", `${x.faults} samples`, "health-faults"],
      ["Backup resets of the phase", String(x.backup_resets), "health-resets"],
      ["Trials recovered after a crash", String(x.trials_recovered), "health-recovered"],
      ["Trials damaged", String(x.trials_damaged), "health-damaged"],
    ]));
  }

  function settings(s) {
    const start = s.settings_start;
    const end = s.settings_end;
    const list = s.settings_history.length
      ? h("ol", { class: "people-history", "data-testid": "settings-history" }, ...s.settings_history.map((r) => h("li", {},
        h("span", { class: "num", text: `${fmt(r.t, 1)} s` }), " ", h("span", { "data-testid": "settings-change", text: r.text }))))
      : h("p", { class: "hint", "data-testid": "settings-history", text: "No setting was changed during the session." });
    return h("section", { class: "card", "data-testid": "report-settings" }, h("h2", { text: "Settings" }),
      dl([
        [SETTING_NAMES.torque_gain.name, start ? `${fmt(start.torque_gain, 2)} at the start, ${fmt(end.torque_gain, 2)} at the end` : fmt(end.torque_gain, 2), "settings-gain"],
        [SETTING_NAMES.max_torque_Nm.name, start ? `${fmt(start.max_torque_Nm, 1)} N·m at the start, ${fmt(end.max_torque_Nm, 1)} N·m at the end` : `${fmt(end.max_torque_Nm, 1)} N·m`, "settings-limit"],
        [SETTING_NAMES.primary.name, estimatorLabel(end.primary), "settings-primary"],
      ]), h("h3", { text: "Changes" }), list);
  }

  function profile(s) {
    const speedBox = h("div", { class: "plot", "data-testid": "profile-speed" });
    const inclineBox = h("div", { class: "plot", "data-testid": "profile-incline" });
    const card = h("section", { class: "card", "data-testid": "report-profile" }, h("h2", { text: "Speed and incline, stride by stride" }),
      s.profile.length ? null : h("p", { class: "hint", text: "No complete stride was recorded." }), speedBox, inclineBox);
    if (s.profile.length) {
      queueMicrotask(() => {
        // the line breaks where time was not recorded (between trials, a gap, strides left out): never bridged
        plot(speedBox, { title: "Speed", yLabel: "m/s", xLabel: "session time (s)", height: 180,
          series: [{ label: "speed", color: COLORS.blue, points: true }] }).setData(profileLine(s.profile, "speed_m_s"));
        plot(inclineBox, { title: "Incline", yLabel: "deg", xLabel: "session time (s)", height: 180,
          series: [{ label: "incline", color: COLORS.orange, points: true }] }).setData(profileLine(s.profile, "incline_deg"));
      });
    }
    return card;
  }

  function conditions(s) {
    const card = h("section", { class: "card", "data-testid": "report-conditions" }, h("h2", { text: "Strides by condition" }));
    if (!s.conditions.length) {
      card.append(h("p", { class: "hint", text: "No complete stride was recorded." }));
      return card;
    }
    const cond = h("select", { id: "overlay-condition", "data-testid": "overlay-condition" },
      ...s.conditions.map((c, i) => h("option", { value: String(i), text: `${c.label} · ${plural(c.strides, "stride")}` })));
    const signals = Object.keys(SIGNALS).filter((k) => s.conditions.some((c) => c.signals[k]));
    const sig = h("select", { id: "overlay-signal", "data-testid": "overlay-signal" },
      ...signals.map((k) => h("option", { value: k, text: SIGNALS[k].label })));
    const box = h("div", { class: "plot", "data-testid": "overlay-plot" });
    const caption = h("p", { class: "hint", "data-testid": "overlay-caption" });
    card.append(h("div", { class: "inline" }, field("Condition", cond), field("Signal", sig)), box, caption,
      h("p", { class: "hint", "data-testid": "conditions-rule", text: "A condition is a speed (to 0.2 m/s) and an incline (to 2.5°) the "
        + "walker held: strides in runs of 3 or more one after the other. "
        + (s.transition_strides ? `${plural(s.transition_strides, "stride")} walked while the speed or incline changed belong to none. ` : "")
        + "Grey: single strides; blue: their mean." }));
    let p = null;
    function draw() {
      const c = s.conditions[Number(cond.value)];
      const k = sig.value;
      const info = SIGNALS[k];
      const overlays = c.overlays[k] || [];
      const series = [...overlays.map((_, i) => ({ label: `stride ${i + 1}`, color: STRIDE_GREY, width: 1 })),
        { label: "mean", color: COLORS.blue, width: 3 }];
      if (p) { // a new title and axis: a new plot
        p.destroy();
        st.plots.splice(st.plots.indexOf(p), 1);
      }
      p = plot(box, { title: `${info.label}, ${c.label}`, yLabel: info.unit, xLabel: "% of the stride", height: 240, series });
      p.setData([c.percent, ...overlays, c.signals[k] || c.percent.map(() => null)]);
      caption.textContent = `${info.label} over the stride at ${c.label}: the mean of ${plural(c.strides, "stride")}, `
        + `${overlays.length === c.strides ? "each" : `${overlays.length} of them`} drawn singly.`;
    }
    cond.addEventListener("change", draw);
    sig.addEventListener("change", draw);
    queueMicrotask(draw);
    return card;
  }

  function events(s) {
    const list = new EventList("report-events");
    list.add(...s.events);
    return h("section", { class: "card", "data-testid": "report-events-card" }, h("h2", { text: `Events (${s.events.length})` }), list.el);
  }

  /** While the server makes the summary: how far it has got, polled (a bar and the gait states read). */
  const fill = h("div", { class: "meter-fill" });
  const bar = h("div", { class: "meter", role: "progressbar", "aria-label": "Summary progress", "aria-valuemin": 0,
    "aria-valuemax": 100, "data-testid": "report-progress", hidden: true }, fill);
  note.after(bar);
  async function watchProgress(done) {
    while (!done.value && st.alive) {
      await new Promise((r) => setTimeout(r, PROGRESS_MS));
      if (done.value || !st.alive) break;
      try {
        const p = await api.summaryProgress(sessionId);
        if (done.value || !p.running) continue;
        const pct = Math.round(100 * p.progress);
        bar.hidden = false;
        fill.style.width = `${pct}%`;
        bar.setAttribute("aria-valuenow", String(pct));
        note.textContent = `Reading the session's recordings: ${pct} % (${p.step}).`;
      } catch {
        break; // the summary's own answer says what went wrong
      }
    }
    bar.hidden = true;
  }

  async function load() {
    const done = { value: false };
    watchProgress(done);
    try {
      const s = await api.summary(sessionId).finally(() => { done.value = true; });
      if (!st.alive) return;
      st.summary = s;
      title.textContent = `Session ${s.session_id} of ${s.subject_code}: summary`;
      note.replaceChildren(`${s.source}, ${STATE_WORDS[s.state] || s.state}. `,
        h("a", { href: `#/subjects/${s.subject_id}`, text: `${s.subject_code}'s page` }), " · ",
        h("a", { href: "#/subjects", text: "all subjects" }),
        s.state === "running" ? " · This session is still running: the summary covers what is recorded so far." : "");
      body.replaceChildren(
        h("div", { class: "people-report-top" }, walking(s), exports.el),
        profile(s), conditions(s),
        h("div", { class: "people-report-pair" }, settings(s), health(s)),
        events(s));
      body.removeAttribute("aria-busy");
    } catch (err) {
      if (!st.alive) return;
      note.textContent = "";
      body.removeAttribute("aria-busy");
      showError(error, err instanceof ApiError && err.status === 404 ? `There is no session ${sessionId}.` : err);
    }
  }

  load();
  return {
    unmount() {
      st.alive = false;
      exports.stop();
      for (const p of st.plots) p.destroy();
    },
  };
}
