// Formatting shared by the people pages (subjects list, session summary): durations and source names in words.

/** Seconds as "1 h 02 min", "3 min 05 s" or "42.0 s". */
export function fmtDuration(s) {
  if (s === null || s === undefined || !Number.isFinite(s)) return "–";
  if (s < 60) return `${s.toFixed(1)} s`;
  const total = Math.round(s);
  const hrs = Math.floor(total / 3600);
  const min = Math.floor((total % 3600) / 60);
  const sec = total % 60;
  const p = (n) => String(n).padStart(2, "0");
  return hrs ? `${hrs} h ${p(min)} min` : `${min} min ${p(sec)} s`;
}

/** A session's length from its start to its stop (or to now while it runs); null before it started. */
export function sessionSeconds(session, now = Date.now()) {
  if (!session.started_utc) return null;
  const end = session.stopped_utc ? Date.parse(session.stopped_utc) : now;
  return Math.max(0, (end - Date.parse(session.started_utc)) / 1000);
}

export const SOURCE_WORDS = { simulated: "simulated walker", replay: "replay of a trial", device: "live device", upload: "uploaded recording" };
export const STATE_WORDS = { created: "not started", running: "running", stopped: "stopped", failed: "stopped on an error" };
export const TRIAL_WORDS = { recording: "recording", finished: "finished", recovered: "recovered after a crash", uploaded: "uploaded",
  damaged: "damaged" };

/** "1 stride", "3 strides". */
export const plural = (n, one, many = `${one}s`) => `${n} ${n === 1 ? one : many}`;
