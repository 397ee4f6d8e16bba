// Playback of a reviewed trial: play/pause, speed (0.5x to 4x real time) and a cursor moving over the plots;
// and the review's keyboard shortcuts (space: play/pause, ← →: step the cursor, + −: zoom in and out around
// it), ignored while the user types in a form field.

import { h } from "./ui.js";

export const SPEEDS = [0.5, 1, 2, 4];
const FRAME_MS = 50; // the cursor moves at most 20 times a second (each move redraws every plot)

/** True when a key press belongs to a form field (typing there must not steer the review). */
export function typing(target) {
  if (!(target instanceof Element)) return false;
  return !!target.closest("input, textarea, select, [contenteditable=''], [contenteditable='true']");
}

/**
 * The playback bar and its clock.
 * @param {{cursor: () => (number | null), setCursor: (t: number) => void, bounds: () => (number[] | null)}} hooks
 *   the cursor's time, moving it, and the trial's [first, last] time
 */
export function playback(hooks) {
  const st = { playing: false, speed: 1, raf: 0, last: 0 };
  const playBtn = h("button", { type: "button", class: "primary", "data-testid": "play", "aria-pressed": "false",
    text: "▶ Play" });
  const speed = h("select", { id: "play-speed", "data-testid": "play-speed", "aria-label": "Playback speed" },
    ...SPEEDS.map((s) => h("option", { value: s, text: `${s}×` })));
  speed.value = "1";
  const el = h("div", { class: "inline playback", "data-testid": "playback" }, playBtn,
    h("label", { for: "play-speed", class: "caption", text: "Speed" }), speed,
    h("span", { class: "hint", text: "Keys: space play/pause, ← → step, + − zoom" }));

  function show() {
    playBtn.textContent = st.playing ? "❚❚ Pause" : "▶ Play";
    playBtn.setAttribute("aria-pressed", String(st.playing));
    el.dataset.state = st.playing ? "playing" : "paused";
  }
  function tick(now) {
    if (!st.playing) return;
    const dt = now - st.last;
    if (dt >= FRAME_MS) {
      st.last = now;
      const b = hooks.bounds();
      const t = hooks.cursor();
      if (!b || t == null) return pause();
      const next = t + (dt / 1000) * st.speed;
      if (next >= b[1]) {
        hooks.setCursor(b[1]);
        return pause();
      }
      hooks.setCursor(next);
    }
    st.raf = requestAnimationFrame(tick);
  }
  function play() {
    const b = hooks.bounds();
    if (!b || st.playing) return;
    if (hooks.cursor() == null || hooks.cursor() >= b[1]) hooks.setCursor(b[0]); // from the start again
    st.playing = true;
    st.last = performance.now();
    st.raf = requestAnimationFrame(tick);
    show();
  }
  function pause() {
    st.playing = false;
    cancelAnimationFrame(st.raf);
    show();
  }
  playBtn.addEventListener("click", () => (st.playing ? pause() : play()));
  speed.addEventListener("change", () => {
    st.speed = Number(speed.value);
  });
  show();
  return { el, play, pause, toggle: () => (st.playing ? pause() : play()), playing: () => st.playing, stop: pause };
}

/**
 * The review's keys on `document` while mounted; returns the function that removes them.
 * @param {{toggle: () => void, step: (dir: number, big: boolean) => void, zoom: (factor: number) => void}} actions
 */
export function reviewKeys(actions) {
  function onKey(ev) {
    if (ev.defaultPrevented || ev.ctrlKey || ev.metaKey || ev.altKey || typing(ev.target)) return;
    if (ev.key === " " || ev.code === "Space") {
      if (ev.target instanceof Element && ev.target.closest("button, a, summary")) return; // their own space
      actions.toggle();
    } else if (ev.key === "ArrowLeft" || ev.key === "ArrowRight") {
      actions.step(ev.key === "ArrowLeft" ? -1 : 1, ev.shiftKey);
    } else if (ev.key === "+" || ev.key === "=") {
      actions.zoom(0.5);
    } else if (ev.key === "-" || ev.key === "_") {
      actions.zoom(2);
    } else {
      return;
    }
    ev.preventDefault();
  }
  document.addEventListener("keydown", onKey);
  return () => document.removeEventListener("keydown", onKey);
}
