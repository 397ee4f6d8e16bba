// The live view's IMU calibration card: "Calibrate IMUs (stand still)" on a session whose stack has IMU front
// ends (imu_foot, imu_shank, ...), a progress bar while the standing period is collected, then the offsets
// each front end took, or the refusal with each sensor's reason. Hidden when the session has no IMU front end.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { errorBox, field, fmt, h, runAction, showError } from "./ui.js";
import { FIELD_LIMITS } from "./wire.js";

const DURATIONS_S = [2, 5, 10, 20, 30].filter((s) => s >= FIELD_LIMITS.ImuCalibrationRequest.duration_s.min
  && s <= FIELD_LIMITS.ImuCalibrationRequest.duration_s.max);
const POLL_MS = 250;

/** One line per sensor: its pitch offset and gyro bias, or why it was refused. */
function sensorLines(cal) {
  return h("ul", { class: "imu-sensors" }, ...cal.sensors.map((s) => h("li", { "data-testid": `imu-sensor-${s.segment}` },
    h("strong", { text: `imu_${s.segment}: ` }),
    s.ok ? `pitch offset ${fmt(s.pitch_offset_deg, 1)} deg, gyro bias ${s.gyro_bias_dps.map((b) => fmt(b, 2)).join(" / ")} deg/s`
      : s.reason)));
}

/**
 * @param {number} sessionId
 * @returns {{el: HTMLElement, refresh: () => Promise<void>}}
 */
export function imuCalibrationCard(sessionId) {
  const duration = h("select", { id: "imu-duration", "data-testid": "imu-duration" },
    ...DURATIONS_S.map((s) => h("option", { value: String(s), text: `${s} s` })));
  duration.value = "5";
  const startBtn = h("button", { type: "button", class: "primary", "data-testid": "imu-calibrate", text: "Calibrate IMUs (stand still)" });
  const fill = h("div", { class: "meter-fill" });
  const bar = h("div", { class: "meter", role: "progressbar", "aria-label": "Standing period collected", "aria-valuemin": 0,
    "aria-valuemax": 100, "data-testid": "imu-bar", hidden: true }, fill);
  const status = h("div", { class: "status-line", "data-testid": "imu-status", "aria-live": "polite" });
  const error = errorBox("imu-error");
  const el = h("section", { class: "card", "data-testid": "imu-card", hidden: true }, h("h2", { text: "IMU calibration" }),
    h("p", { class: "hint", text: "The subject stands upright and still; each sensor's mounting offset and gyro bias are then applied." }),
    h("div", { class: "inline" }, field("Standing period", duration), startBtn), bar, status, error);
  fence(el, "run");
  let timer = 0;

  function render(st) {
    el.hidden = st.segments.length === 0 && st.applied === null;
    const collecting = st.state === "collecting";
    startBtn.disabled = collecting || st.segments.length === 0;
    bar.hidden = !collecting;
    const pct = Math.round(100 * st.progress);
    fill.style.width = `${pct}%`;
    bar.setAttribute("aria-valuenow", String(pct));
    status.replaceChildren();
    if (collecting) {
      status.append(`Stand still… ${fmt(st.progress * st.duration_s, 1)} s of ${fmt(st.duration_s, 0)} s`);
    } else if (st.state === "refused") {
      status.append(h("p", { class: "error", "data-testid": "imu-refused", text: "Refused, nothing applied:" }), sensorLines(st.result),
        ...(st.result.sensors.length ? [] : [h("p", { text: st.result.reason })]));
    } else if (st.applied) {
      const own = st.result && st.result.id === st.applied.id;
      status.append(h("p", { class: "ok", "data-testid": "imu-applied",
        text: own ? `Applied (calibration ${st.applied.id}):` : `The subject's calibration ${st.applied.id} (${st.applied.created_utc}) applies:` }),
      sensorLines(st.applied));
    } else {
      status.append(`Not calibrated: ${st.segments.map((s) => `imu_${s}`).join(", ")} run without a mounting offset.`);
    }
    clearTimeout(timer);
    if (collecting) timer = setTimeout(() => refresh(), POLL_MS);
  }

  async function refresh() {
    if (!el.isConnected && timer) return; // the view was left
    try {
      render(await api.imuCalibration(sessionId));
    } catch (err) {
      showError(error, err);
    }
  }

  startBtn.addEventListener("click", () => runAction(startBtn, error, async () => {
    render(await api.startImuCalibration(sessionId, { duration_s: Number(duration.value) }));
  }));
  return { el, refresh };
}
