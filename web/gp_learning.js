// The live view's GP-EKF card (seed 003, issue #11): a session whose stack runs `gp_ekf` learns the wearer's
// joint angles over the stance phase, retraining in the background every 5 completed stances. The card shows
// the filter's stance-phase estimate (last 10 s), the learned mean of the hip, knee and ankle angle with its
// +-2 SD band for the version in use (another kept version faintly, to compare), which version is installed,
// waiting for the next heel strike or being fitted, the kept versions with their training window and
// held-out RMSE, and the clinician's controls: freeze / unfreeze learning, roll back to a kept version.
// State: `GET /api/sessions/{id}/gp-learning` (GPLearningState), polled every 2 s while the session runs and
// at once on a `gp_ekf` event; controls: `POST` the same (GPLearningControl), logged with the logged-in user.
// Hidden for a session without `gp_ekf` (it is opt-in: the session's settings must name it).

import { ApiError, errorText } from "./api.js";
import { LEARNER } from "./estimators.js";
import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { COLORS, Plot, Ring } from "./plots.js";
import { errorBox, field, fmt, h, runAction } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

/** The GP-EKF's name in a stack: the estimator that learns a model online (its descriptor's `learned_model`). Its
 * `phase` output is the STANCE phase (0 at heel strike, 1 at toe-off). */
export const GP_EKF = LEARNER;
const POLL_MS = 2000;
const STANCE_WINDOW_S = 10;
/** The joints of its observation models (sessions/schema.py GP_JOINTS), each with its plot's colours. */
const JOINTS = [
  { key: "hip", label: "Hip", color: COLORS.purple, line: "#b794d9", band: "rgba(107,33,168,0.16)" },
  { key: "knee", label: "Knee", color: COLORS.green, line: "#7fbf93", band: "rgba(29,122,58,0.16)" },
  { key: "ankle", label: "Ankle", color: COLORS.blue, line: "#7fa6d1", band: "rgba(11,92,173,0.16)" },
];

const span = (a) => (a ? `${fmt(a[0], 1)}–${fmt(a[1], 1)}` : "–");

/**
 * The version installed before the one in use (by their latest installs; the population model when the
 * one in use was installed once and nothing before it): what the bands are compared with by default.
 * @param {object} st GPLearningState
 * @returns {number | null}
 */
export function previousVersion(st) {
  const last = (v) => (v.installed_t.length ? Math.max(...v.installed_t) : v.population ? -Infinity : null);
  const cur = st.versions.find((v) => v.version === st.version);
  const tCur = cur ? last(cur) : null;
  if (tCur == null || tCur === -Infinity) return null;
  let best = null;
  for (const v of st.versions) {
    const t = last(v);
    if (v.version !== st.version && t != null && t < tCur && (best === null || t > best.t)) best = { t, version: v.version };
  }
  return best && best.version;
}

/** A joint's band plot: the mean, its +-2 SD band, and a kept version's mean to compare (faint, dashed). */
function jointPlot(container, joint, current, compare) {
  return new Plot(container, {
    title: `${joint.label} angle`, yLabel: "deg", xLabel: "% of stance", xRange: [0, 100], height: 180,
    series: jointSeries(joint, current, compare), bands: [{ series: [3, 2], fill: joint.band }],
  });
}

function jointSeries(joint, current, compare) {
  return [
    { label: `v${current} mean`, color: joint.color, width: 2.5 }, { label: "−2 SD", color: joint.line, width: 1 },
    { label: "+2 SD", color: joint.line, width: 1 },
    { label: compare.label, color: "#6b7280", dash: [5, 4], width: 1.5 },
  ];
}

/** What the GP-EKF is doing, as badges: the version installed, one waiting, a fit under way or queued, frozen. */
function statusBadges(state) {
  const pending = state.pending;
  const population = state.versions.find((v) => v.version === state.version && v.population);
  return [
    h("span", { class: "badge badge-active", "data-testid": "gp-version", "data-version": state.version,
      text: `v${state.version}` }), ` installed${population ? " (population model)" : ""}`,
    state.waiting === null ? null : h("span", { class: "badge badge-candidate", "data-testid": "gp-waiting",
      text: `v${state.waiting} waiting for the next heel strike${state.rollback ? " (rollback)" : ""}` }),
    pending ? h("span", { class: "badge badge-average", "data-testid": "gp-pending",
      text: `fitting v${pending.version} on steps ${pending.steps[0]}–${pending.steps[1]} (${span(pending.span_s)} s)` }) : null,
    state.queued_s === null || state.queued_s === undefined || pending ? null : h("span", {
      class: "badge badge-average", "data-testid": "gp-queued",
      text: `next window waiting ${state.queued_s.toFixed(0)} s for the fitting worker (shared by the server's learning sessions)` }),
    state.frozen ? h("span", { class: "badge badge-frozen", "data-testid": "gp-frozen", text: "FROZEN: not learning" }) : null,
  ].filter((c) => c !== null);
}

/** The kept versions, newest first: steps, time span, held-out RMSE per joint, when installed. */
function versionRows(state) {
  return [...state.versions].reverse().map((v) => {
    const inUse = v.version === state.version;
    const tags = [inUse ? "in use" : null, v.version === state.waiting ? "waiting" : null].filter(Boolean);
    const installs = [...(v.population ? ["start"] : []), ...v.installed_t.map((t) => fmt(t, 1))];
    return h("tr", { class: inUse ? "is-active" : "", "data-testid": "gp-version-row", "data-version": v.version },
      h("th", { scope: "row", "data-label": "Version" }, `v${v.version}`, v.population ? h("div", { class: "hint", text: "population" }) : null,
        tags.length ? h("div", { class: "hint", text: tags.join(", ") }) : null),
      h("td", { class: "num", "data-label": "Steps", text: v.steps ? `${v.steps[0]}–${v.steps[1]}` : "cohort" }),
      h("td", { class: "num", "data-label": "Time span (s)", text: span(v.span_s) }),
      ...JOINTS.map((j) => h("td", { class: "num", "data-label": `RMSE ${j.key} (deg)`, text: fmt(v.rmse_deg[j.key], 1) })),
      h("td", { class: "num", "data-label": "Installed at (s)", text: installs.join(", ") || "–" }));
  });
}

/** The GP-EKF's stance phase streamed: the last 10 s in a ring, its plot, and the newest phase and rate in words. */
class StanceTrace {
  /** @param {HTMLElement} nowEl where the newest stance phase and rate are written */
  constructor(nowEl) {
    this.nowEl = nowEl;
    this.ring = new Ring(2048, ["t", "stance_pct"]); // > 10 s at the 60 Hz the stream is asked for
    this.lastT = -Infinity;
    this.lastRate = NaN;
    this.dirty = false;
    this.lastText = 0;
    this.stance = null;
  }

  /** Its plot, in `div`, following the newest `STANCE_WINDOW_S` seconds (`follow`). */
  plot(div, follow) {
    this.stance = new Plot(div, { title: "Stance phase (GP-EKF), last 10 s", yLabel: "% of stance", yRange: [0, 100],
      xRange: follow, height: 150, series: [{ label: "stance phase", color: COLORS.teal, width: 2 }] });
    return this.stance;
  }

  /** A batch's states and the GP-EKF's outputs at the same samples (phase, phase_rate). */
  push(states, est) {
    const phase = est.columns.phase;
    const rate = est.columns.phase_rate;
    for (let i = 0; i < states.length; i++) {
      if (states[i].t < this.lastT) this.ring.clear(); // the source restarted
      this.lastT = states[i].t;
      this.ring.push({ t: this.lastT, stance_pct: phase[i] == null ? null : 100 * phase[i] });
      if (rate && rate[i] != null) this.lastRate = rate[i];
    }
    if (states.length) this.dirty = true;
  }

  /** Redrawn from the live view's animation frame loop (the words at most 5 times a second). */
  frame(now) {
    if (this.dirty && this.stance) {
      this.dirty = false;
      this.stance.setData(this.ring.window("t", ["stance_pct"], STANCE_WINDOW_S));
    }
    if (now - this.lastText > 200) {
      this.lastText = now;
      this.nowEl.textContent = `stance phase ${fmt(this.ring.last("stance_pct"), 0)} %, rate ${fmt(this.lastRate, 2)} /s`;
    }
  }
}

/**
 * The joints' bands of the version in use, and the compared version's mean when the state carries it.
 * @returns {boolean} false when the state lacks the band of the version to compare with
 */
function drawBands(plots, bandDivs, state, compare) {
  const x = state.phase.map((p) => 100 * p);
  const req = state.requested && state.requested.version === compare ? state.requested : null;
  const prev = previousVersion(state);
  const label = req ? `v${req.version} mean (${req.version === prev ? "previous" : "chosen below"})` : "compare: none";
  JOINTS.forEach((j, i) => {
    const plot = plots.bands[i];
    plot.setSeries(jointSeries(j, state.current.version, { label }));
    const cur = state.current;
    plot.setData([x, cur.mean_deg[j.key], cur.lower_deg[j.key], cur.upper_deg[j.key],
      req ? req.mean_deg[j.key] : x.map(() => null)]);
    bandDivs[i].dataset.version = String(cur.version);
    bandDivs[i].dataset.compare = req ? String(req.version) : "";
  });
  return compare === null || req !== null;
}

/** The card's elements (hidden until the stack is known to run gp_ekf). */
function cardElements() {
  const badges = h("div", { class: "gp-badges", "data-testid": "gp-status", "aria-live": "polite" });
  const last = h("p", { class: "hint", "data-testid": "gp-last" });
  const stanceNow = h("span", { class: "gp-now", "data-testid": "gp-stance-now", text: "–" });
  const stanceDiv = h("div", { class: "plot", "data-testid": "gp-stance-plot" });
  const bandDivs = JOINTS.map((j) => h("div", { class: "plot", "data-testid": `gp-band-${j.key}` }));
  const versionsBody = h("tbody", {});
  const versionsTable = h("div", { class: "table-scroll" }, h("table", { class: "table versions gp-versions", "data-testid": "gp-versions" },
    h("caption", { class: "hint", text: "Held-out RMSE: each window's last stance, left out of the fit, predicted by that version (deg)." }),
    h("thead", {}, h("tr", {}, ...["Version", "Steps", "Time span (s)", "Hip", "Knee", "Ankle", "Installed at (s)"]
      .map((t) => h("th", { scope: "col", text: t })))), versionsBody));
  // a toggle whose label says what it does next (no aria-pressed, which would contradict the changing label)
  const freezeBtn = h("button", { type: "button", "data-testid": "gp-freeze", text: "Freeze learning" });
  const rollbackSel = h("select", { id: "gp-rollback-version", "data-testid": "gp-rollback-version" });
  const rollbackBtn = h("button", { type: "button", "data-testid": "gp-rollback", text: "Roll back" });
  const reason = h("input", { id: "gp-reason", "data-testid": "gp-reason", placeholder: "reason (optional, logged)",
    maxlength: FIELD_LIMITS.GPLearningControl.reason.maxLength, autocomplete: "off" });
  const error = errorBox("gp-error");
  const ok = h("p", { class: "ok", role: "status", "data-testid": "gp-ok" });
  const note = h("p", { class: "note", "data-testid": "gp-note" });
  const el = h("section", { class: "card gp-card", "data-testid": "gp-card", hidden: true },
    h("div", { class: "card-head" }, h("h2", { text: "Learning gait model (GP-EKF, seed 003)" }), stanceNow),
    h("p", { class: "hint", text: "The GP-EKF estimates the stance phase (0 % at heel strike, 100 % at toe-off, held in swing) "
      + "from the hip, knee and ankle angles, with a model of them learnt from this walker: refitted every 5 stances in "
      + "the background, checked on a held-out stance and installed at a heel strike." }),
    badges, last, note, h("div", { class: "gp-bands" }, ...bandDivs),
    h("div", { class: "gp-lower" }, stanceDiv,
      h("div", {}, versionsTable,
        fence(h("div", { class: "inline gp-controls" }, freezeBtn, field("Compare with / roll back to", rollbackSel), rollbackBtn, reason), "run"),
        error, ok)));
  return { el, badges, last, stanceNow, stanceDiv, bandDivs, versionsBody, freezeBtn, rollbackSel, rollbackBtn, reason, error, ok, note };
}

/**
 * @param {number} sessionId
 */
export function gpLearningCard(sessionId) {
  const { el, badges, last, stanceNow, stanceDiv, bandDivs, versionsBody, freezeBtn, rollbackSel, rollbackBtn, reason, error, ok,
    note } = cardElements();

  let has = false; // the stack runs gp_ekf
  let running = false;
  let st = null; // the last GPLearningState shown
  let chosen = null; // the version picked in the select (null: follow the previous one)
  let timer = 0;
  let seq = 0; // requests sent; a response older than the last one shown is dropped
  let shownSeq = 0;
  let inFlight = false;
  let retry = false; // the last poll is being repeated at once for the compared version's band
  let dead = false;
  let plots = null; // built when first shown: {stance, bands: Plot[]}
  const trace = new StanceTrace(stanceNow);

  function build() {
    if (plots) return;
    const follow = (u, min, max) => (max == null ? [0, STANCE_WINDOW_S] : [max - STANCE_WINDOW_S, max]);
    plots = {
      stance: trace.plot(stanceDiv, follow),
      bands: JOINTS.map((j, i) => jointPlot(bandDivs[i], j, 0, { label: "compare: none" })),
    };
  }

  function show() {
    if (!has || !el.hidden) return;
    el.hidden = false;
    build();
    schedule(0);
  }

  /** The version the faint curve shows and the select offers: the pick, else the previous one, else the
   * newest other kept one (null: none is kept). */
  function compareVersion(state) {
    const others = state.versions.map((v) => v.version).filter((v) => v !== state.version);
    if (chosen !== null && others.includes(chosen)) return chosen;
    chosen = null;
    return previousVersion(state) ?? (others.length ? Math.max(...others) : null);
  }

  /** Shows a state; false when it lacks the band of the version to compare with (fetch it now). */
  function render(state) {
    // a control's answer has no compared band: the last poll's stays until the next one
    const kept = st && st.requested && !state.requested ? st.requested : null;
    st = kept ? { ...state, requested: kept } : state;
    state = st;
    badges.replaceChildren(...statusBadges(state));
    last.textContent = state.last || "No retraining yet: the first window is offered after 5 completed stances.";
    freezeBtn.textContent = state.frozen ? "Unfreeze learning" : "Freeze learning";
    const compare = compareVersion(state);
    const options = state.versions.filter((v) => v.version !== state.version).reverse();
    rollbackSel.replaceChildren(...options.map((v) => h("option", { value: String(v.version),
      text: `v${v.version}${v.population ? " (population)" : ` · steps ${v.steps[0]}–${v.steps[1]}`}` })));
    if (compare !== null) rollbackSel.value = String(compare);
    rollbackSel.disabled = !options.length;
    rollbackBtn.disabled = !options.length || !running;
    freezeBtn.disabled = !running;
    rollbackBtn.textContent = options.length ? `Roll back to v${rollbackSel.value}` : "Roll back (no other version kept)";
    versionsBody.replaceChildren(...versionRows(state));
    build();
    return drawBands(plots, bandDivs, state, compare);
  }

  function schedule(ms) {
    clearTimeout(timer);
    timer = 0;
    if (!dead && has && running && !el.hidden) timer = setTimeout(refresh, ms);
  }

  /** GET the state (with the compared version's band) and show it; a refusal stops the polling. */
  async function refresh() {
    if (dead || !has || !running) return;
    if (inFlight) return schedule(POLL_MS);
    inFlight = true;
    const mine = ++seq;
    try {
      const compare = st ? compareVersion(st) : null;
      const state = await api.gpLearning(sessionId, { version: compare });
      let complete = true;
      if (mine > shownSeq && !dead) {
        shownSeq = mine;
        note.textContent = "";
        complete = render(state);
      }
      retry = !complete && !retry; // once: a state that changed under the request; never a loop
      schedule(retry ? 0 : POLL_MS);
    } catch (err) {
      if (err instanceof ApiError && err.status === 422) {
        chosen = null; // the compared version is no longer kept: the next poll compares with the previous one
        st = null;
        schedule(0);
      } else if (err instanceof ApiError && err.status === 409) {
        note.textContent = `Learning stopped: ${errorText(err)}`;
        setRunning(false);
      } else {
        note.textContent = errorText(err);
        schedule(POLL_MS);
      }
    } finally {
      inFlight = false;
    }
  }

  /** POST a control; the answer (the new state) is shown at once, newer than any poll under way. */
  async function control(body, done) {
    const state = await api.controlGpLearning(sessionId, { ...body, reason: reason.value.trim() });
    shownSeq = ++seq;
    reason.value = "";
    render(state);
    ok.textContent = done(state);
    schedule(0); // and the compared version's band, which a control's answer does not carry
  }

  freezeBtn.addEventListener("click", () => {
    ok.textContent = "";
    const freeze = !(st && st.frozen);
    runAction(freezeBtn, error, () => control({ action: freeze ? "freeze" : "unfreeze" },
      (s) => (s.frozen ? `Learning frozen: v${s.version} stays until unfrozen or rolled back.` : "Learning resumed."))
    ).then(() => { freezeBtn.disabled = !running; });
  });
  rollbackSel.addEventListener("change", () => {
    chosen = Number(rollbackSel.value);
    rollbackBtn.textContent = `Roll back to v${rollbackSel.value}`;
    schedule(0); // fetch the chosen version's band
  });
  rollbackBtn.addEventListener("click", () => {
    ok.textContent = "";
    const version = Number(rollbackSel.value);
    runAction(rollbackBtn, error, () => control({ action: "rollback", version },
      (s) => (s.waiting === version ? `Rollback to v${version} asked: installed at the next heel strike.` : `v${s.version} in use.`))
    ).then(() => { rollbackBtn.disabled = !running || !rollbackSel.options.length; });
  });

  function setRunning(r) {
    running = r;
    freezeBtn.disabled = !r;
    rollbackBtn.disabled = !r || !rollbackSel.options.length;
    if (!r && has && st) note.textContent ||= "The session is not running: its GP-EKF learns only while it runs.";
    schedule(0);
  }

  return {
    el,
    /** A `Session` (hello, start/stop): running or not; a stack naming gp_ekf shows the card. */
    setSession(session) {
      const names = session.settings && session.settings.estimators;
      if (names && names.includes(GP_EKF)) has = true;
      setRunning(session.state === "running");
      show();
    },
    /** The stack a health message names. */
    setStack(names) {
      if (!names || !names.includes(GP_EKF) || has) return;
      has = true;
      show();
    },
    /** A `gp_ekf` event: the state changed, fetch it now. */
    onEvent() {
      schedule(0);
    },
    /**
     * A batch's gait states and the GP-EKF's streamed outputs at the same samples (phase, phase_rate).
     * @param {object[]} states @param {{failed: boolean, columns: Record<string, (number|null)[]>} | undefined} est
     */
    push(states, est) {
      if (!est || !est.columns || !est.columns.phase) return;
      if (!has) {
        has = true;
        show();
      }
      trace.push(states, est);
      if (est.failed) note.textContent = "The GP-EKF has failed (data health says why): its estimate and learning stopped.";
    },
    /** Redraw from the animation frame loop of the live view. */
    frame(now) {
      if (!plots || el.hidden) return;
      trace.frame(now);
    },
    destroy() {
      dead = true;
      clearTimeout(timer);
      if (plots) {
        plots.stance.destroy();
        for (const p of plots.bands) p.destroy();
      }
    },
  };
}
