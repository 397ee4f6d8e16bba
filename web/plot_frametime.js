// Browser-side frame-time measurement: requestAnimationFrame intervals over a few seconds. An e2e test
// calls it through `page.evaluate(async () => (await import("/plot_frametime.js")).measureFrames(5))`.

/**
 * Measures the page's frame rate for `seconds`: the intervals between animation frames.
 * @param {number} seconds how long to measure (0.5-60)
 * @returns {Promise<{seconds: number, frames: number, fps: number, mean_ms: number, p50_ms: number,
 *   p95_ms: number, max_ms: number, over_20ms: number}>} `over_20ms`: frames that took longer than 20 ms
 *   (missed a 60 Hz refresh)
 */
export function measureFrames(seconds = 5) {
  if (!(seconds >= 0.5 && seconds <= 60)) throw new Error(`measureFrames: seconds must be 0.5-60, not ${seconds}`);
  return new Promise((resolve) => {
    const dts = [];
    let first = null;
    let prev = null;
    const step = (now) => {
      if (first === null) first = now;
      else dts.push(now - prev);
      prev = now;
      if (now - first < seconds * 1000) requestAnimationFrame(step);
      else resolve(frameStats(dts, (now - first) / 1000));
    };
    requestAnimationFrame(step);
  });
}

/** Statistics of frame intervals (ms) measured over `elapsed` seconds. */
export function frameStats(dts, elapsed) {
  const sorted = [...dts].sort((a, b) => a - b);
  const q = (p) => (sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(p * sorted.length))] : NaN);
  const mean = sorted.length ? sorted.reduce((s, v) => s + v, 0) / sorted.length : NaN;
  return { seconds: elapsed, frames: dts.length, fps: elapsed > 0 ? dts.length / elapsed : NaN, mean_ms: mean,
    p50_ms: q(0.5), p95_ms: q(0.95), max_ms: sorted.length ? sorted[sorted.length - 1] : NaN,
    over_20ms: dts.filter((d) => d > 20).length };
}
