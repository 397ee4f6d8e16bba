// Live view (`#/sessions/{id}`): the session's stream in plots redrawn once per animation frame, the
// per-stride overlay, data health, controls, events and the 3D leg view. The phase plot overlays the phase
// of every estimator of the session's stack (the primary, which drives the torque, drawn widest). A stack with
// the speed-change intent estimator (seed 001) adds its desired vs actual speed, its detections marked. The
// hip and knee flexion come from the gait state's thigh and shank angles (sensed, or derived from raw IMUs by
// the stack's front ends); a stack with the SDRE estimator (`sdre_knee`, seed 002) adds its knee, dashed. A stack
// with the GP-EKF (`gp_ekf`, seed 003) gets its card (`gp_learning.js`): its phase is the STANCE phase, plotted
// there and kept out of the gait-phase plot.
//
// Layout (issue #12): panels in a grid (`live_layout.js`: which, their order and width, remembered per logged-in
// user), the key plots (phase, torque, phase rate, incline) first, in view without scrolling at 1440x900; on
// a phone the data health and the stop control come first. The time plots are one `PlotGroup`: pause and
// resume (data keeps arriving), zoom and pan a paused view, linked cursors with hover values, the setting
// changes and annotations as labelled markers. A new connection gets the session's last 30 s first (the
// server's history), so the plots open full. The health box judges the figures (`live_health.js`); the stream
// reconnects by itself, at once when the server is back, and says what happened to a session that ended.
//
// Issue #23: a status strip (`live_status.js`) above the panels holds what must stay in sight on a tablet: the
// session's state and Stop, LIVE, the recording state (also in the header while a trial records) and the
// summary figures; Space pauses and resumes the plots.
//
// Components (issue #22): the time plots and their ring (`live_plots.js`, whose plot specs the review shares),
// the per-stride overlays and baseline (`live_strides.js`), the summary figures (`live_summary.js`), the
// estimator stack and the primary's switch (`live_stack.js`), the panels (`live_layout.js`).

import { openSessionStream } from "./api.js";
import * as api from "./api_client.js";
import { currentUser } from "./auth.js";
import { mountControls } from "./controls.js";
import { deviceCredentialsCard } from "./device_credentials.js";
import { INTENT } from "./estimators.js";
import { EventList, isSettingChange } from "./events.js";
import { GP_EKF, gpLearningCard } from "./gp_learning.js";
import { legView } from "./leg_view.js";
import { HealthBox } from "./live_health_box.js";
import { livePanels, PanelLayout } from "./live_layout.js";
import { LivePlots } from "./live_plots.js";
import { LiveStack } from "./live_stack.js";
import { sessionEndBanner } from "./live_session_end.js";
import { StrideCard } from "./live_strides.js";
import { LiveSummary } from "./live_summary.js";
import { liveStatus } from "./live_status.js";
import { PlotGroup } from "./plots.js";
import { onServerChange } from "./server_status.js";
import { errorBox, h, showError } from "./ui.js";

export function mountLive(root, sessionId) {
  const events = new EventList("events-list");
  const group = new PlotGroup({ pauseOnZoom: true });
  let lastText = 0;
  let raf = 0;
  let lastStatePoll = performance.now();
  let alive = true;
  let helloWall = 0; // Date.now() at the last hello: states the server had before it are the history
  let serverLost = false; // the page lost the server since the stream last opened
  let ended = false;

  // --- header, summary, health --------------------------------------------------------------------
  const title = h("h1", { "data-testid": "live-title", text: `Session ${sessionId}` });
  const streamError = errorBox("stream-error");
  const summary = new LiveSummary();

  const healthBox = new HealthBox();
  // the estimators, the primary and its switch (in the health box), the failures (live_stack.js)
  const stack = new LiveStack(sessionId, healthBox.f, { setSession: (session) => controls.setSession(session),
    primary: (primary) => summary.setPrimary(primary), stack: (...args) => plots.setStack(...args) });
  healthBox.el.append(...stack.els);

  // --- plots: one group (shared zoom, cursor, markers, pause), the per-stride overlays -----------------
  const plots = new LivePlots(group);
  const strides = new StrideCard();
  function showMarkers() {
    const all = [...events.events.values()];
    plots.setMarkers(all);
    const settings = all.filter(isSettingChange).sort((a, b) => a.t - b.t || a.id - b.id);
    controls.setLastChange(settings.length ? settings[settings.length - 1] : null);
  }
  const addEvents = (...evs) => {
    events.add(...evs);
    showMarkers();
  };

  // --- controls, events, leg view, panels ------------------------------------------------------------
  let subjectCode = "";
  const sessionEnd = sessionEndBanner();
  const gp = gpLearningCard(sessionId);
  const credentials = deviceCredentialsCard(sessionId);
  const controls = mountControls(sessionId, {
    onEvent: (ev) => addEvents(ev),
    onSession: (s) => {
      title.textContent = `Session ${sessionId} · ${subjectCode || `subject ${s.subject_id}`} · ${s.source.kind} · ${s.state}`;
      gp.setSession(s);
      credentials.setSession(s);
      group.setContext({ max_torque_Nm: s.settings.max_torque_Nm });
      if (s.state === "running") sessionEnd.hide();
      else status.recording.refresh(); // stopping the session finished its recording
    },
  });
  const panels = livePanels({ keyBox: plots.keyBox, health: healthBox.el,
    controls: controls.cards, overlays: strides.el, events: events.el, moreBox: plots.moreBox,
    leg: legView({ session_id: sessionId }), gp: gp.el, credentials: credentials.el });
  const layout = new PanelLayout(panels, currentUser().name);
  const status = liveStatus(sessionId, group, { session: controls.cards.session, indicator: healthBox.indicator, summary: summary.el });
  const page = h("div", { class: "page live-page" },
    h("div", { class: "page-head" }, title, plots.pauseNote, plots.pauseBtn, layout.menu, h("a", { class: "button", href: "#/", text: "← Sessions" })),
    status.el, streamError, sessionEnd.el, layout.grid);
  root.append(page);
  strides.start();

  // --- stream ---------------------------------------------------------------------------------------
  function onStates(states, estimators) {
    // the history the server sends on connecting (received before the hello): plotted, not live
    const history = states.length > 0 && states[states.length - 1].recv_ns / 1e6 < helloWall - 50;
    if (!history) healthBox.noteStates(states);
    const est = estimators || {};
    for (const s of states) if (s.sources) summary.setSources(s.sources, s.torque_assumes);
    stack.fromBatch(est);
    summary.showIntent(INTENT ? est[INTENT] : undefined);
    gp.push(states, est[GP_EKF]);
    plots.push(states, est, history, stack.names, (s, row) => strides.push(s.t, row, s.heel_strike));
  }

  function onHealth(m) {
    healthBox.onHealth(m);
    if (m.estimators) {
      gp.setStack(m.estimators);
      stack.fromHealth(m);
    }
  }

  /** The session is not running (anymore): what happened, and the way to start again. */
  async function checkEnded() {
    try {
      const [s, evs] = await Promise.all([api.getSession(sessionId), api.sessionEvents(sessionId)]);
      if (!alive) return;
      controls.setSession(s);
      addEvents(...evs);
      if (s.state === "stopped" || s.state === "failed") {
        ended = true;
        healthBox.ended = true;
        sessionEnd.show(s, evs, serverLost);
        healthBox.setConnection("not streaming: the session is not running", false);
      }
    } catch (err) {
      if (alive) showError(streamError, err);
    }
  }

  const handlers = {
    /** @param {import("./wire.js").BrowserMessage} msg */
    onMessage(msg) {
      switch (msg.type) {
        case "hello":
          helloWall = Date.now();
          serverLost = false;
          showError(streamError, null);
          subjectCode = msg.subject.code;
          healthBox.declaredHz = msg.source_rate_hz;
          strides.setSubject(msg.subject.code);
          controls.setSession(msg.session);
          stack.primary = msg.session.settings.primary ?? null; // the health messages then say which drives it
          break;
        case "states":
          onStates(msg.states, msg.estimators);
          break;
        case "health":
          onHealth(msg);
          break;
        case "event":
          addEvents(msg.event);
          if (msg.event.kind === "recording" || msg.event.kind === "system") Promise.all([controls.refreshRecording(), status.recording.refresh()]);
          if (msg.event.field === GP_EKF) gp.onEvent();
          break;
        case "settings":
          controls.setSettings(msg.settings);
          group.setContext({ max_torque_Nm: msg.settings.max_torque_Nm });
          stack.fromSettings(msg.settings);
          break;
        default:
          break; // message types this view does not use
      }
    },
    onStatus(status, info) {
      if (status === "open") healthBox.setConnection("connected", true);
      else if (status === "connecting") healthBox.setConnection("connecting…", false);
      else if (status === "reconnecting") {
        if (info.code === 1006) serverLost = true; // the connection failed or dropped: the server may be gone
        healthBox.setConnection(`connection lost (code ${info.code}); retrying in ${(info.delayMs / 1000).toFixed(1)} s`, false);
      } else if (status === "closed") {
        healthBox.setConnection("not streaming", false);
        showError(streamError, `No live data: ${info.reason || `the server closed the stream (code ${info.code})`}.`);
        checkEnded().then(() => ended && showError(streamError, null));
      }
    },
  };
  let stream = openSessionStream(sessionId, handlers);
  // The header's health check saw the server come back: reconnect now rather than at the next back-off.
  const stopWatching = onServerChange((d) => {
    if (d.state === "lost") serverLost = true;
    if (d.state === "back" && alive && !ended && !healthBox.connected) {
      stream.close();
      stream = openSessionStream(sessionId, handlers);
    }
  });

  // --- drawing: at most once per animation frame, whatever the message rate ---------------------------
  function frame(now) {
    raf = requestAnimationFrame(frame);
    plots.draw();
    strides.draw();
    if (now - lastText > 200) {
      lastText = now;
      const verdict = healthBox.update(now, plots.last("t"));
      controls.editor.showRateLimits(now);
      // The stream stays open, silent, when another screen stops the session: ask for its state.
      if (!verdict.live && !ended && healthBox.connected && now - lastStatePoll > 5000) {
        lastStatePoll = now;
        api.getSession(sessionId).then((s) => {
          if (!alive) return;
          controls.setSession(s);
          if (s.state !== "running" && s.state !== "created") checkEnded();
        }).catch(() => {});
      }
      plots.readouts();
      summary.update((c) => plots.last(c), strides.overlay, stack.primary);
    }
    gp.frame(now);
  }
  raf = requestAnimationFrame(frame);

  api.sessionEvents(sessionId).then((evs) => addEvents(...evs)).catch((err) => showError(streamError, err));

  return {
    unmount() {
      alive = false;
      cancelAnimationFrame(raf);
      stopWatching();
      status.destroy();
      stream.close();
      plots.destroy();
      strides.destroy();
      gp.destroy();
    },
  };
}
