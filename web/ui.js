// Shared DOM helpers: element builder, number formatting, input validation, error display.
// (Kept out of app.js so views can import them without an import cycle with the router.)

import { errorText } from "./api.js";

/**
 * Creates an element. `props`: `class`, `text`, `on<event>` handlers, `value`/`checked`/`disabled`/
 * `hidden` as properties, anything else (ids, `data-testid`, aria-*) as attributes.
 */
export function h(tag, props = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(props || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k === "class") el.className = v;
    else if (k === "text") el.textContent = v;
    else if (k.startsWith("on") && typeof v === "function") el.addEventListener(k.slice(2), v);
    else if (k === "value" || k === "checked" || k === "disabled" || k === "hidden") el[k] = v;
    else el.setAttribute(k, v === true ? "" : String(v));
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

/** A number with `digits` decimals, or an en dash when missing. */
export function fmt(x, digits = 2) {
  if (x === null || x === undefined || !Number.isFinite(x)) return "–";
  const s = x.toFixed(digits);
  return /^-0(\.0+)?$/.test(s) ? s.slice(1) : s; // no "-0.0"
}

/** An ISO-8601 UTC string as local "YYYY-MM-DD HH:MM" (compact enough for a tablet's table). */
export function fmtUtc(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  if (Number.isNaN(d.getTime())) return iso;
  const p = (n) => String(n).padStart(2, "0");
  return `${d.getFullYear()}-${p(d.getMonth() + 1)}-${p(d.getDate())} ${p(d.getHours())}:${p(d.getMinutes())}`;
}

/** Shows an error (an Error, ApiError or text) in a message element next to its control; null clears. */
export function showError(el, err) {
  if (!el) return;
  if (err === null || err === undefined || err === "") {
    el.textContent = "";
    el.hidden = true;
    return;
  }
  el.textContent = typeof err === "string" ? err : errorText(err);
  el.hidden = false;
}

/** An input whose value did not pass validation; the message names the field in plain words. */
export class ValidationError extends Error {}

/**
 * Reads a number from an input and checks it.
 * @param {HTMLInputElement} input
 * @param {{label: string, min?: number, max?: number, integer?: boolean, optional?: boolean}} rule
 * @returns {number|null} null only when `optional` and empty
 */
export function readNumber(input, rule) {
  const raw = input.value.trim();
  if (raw === "") {
    if (rule.optional) return null;
    throw new ValidationError(`${rule.label} is required.`);
  }
  const x = Number(raw);
  if (!Number.isFinite(x)) throw new ValidationError(`${rule.label} must be a number.`);
  if (rule.integer && !Number.isInteger(x)) throw new ValidationError(`${rule.label} must be a whole number.`);
  if (rule.min !== undefined && x < rule.min) throw new ValidationError(`${rule.label} must be at least ${rule.min}.`);
  if (rule.max !== undefined && x > rule.max) throw new ValidationError(`${rule.label} must be at most ${rule.max}.`);
  return x;
}

/**
 * Runs an async action from a button: disables it meanwhile, clears then shows errors in `errorEl`.
 * Returns the action's result, or undefined when it failed (the error is shown, not thrown).
 */
export async function runAction(button, errorEl, action) {
  showError(errorEl, null);
  if (button) button.disabled = true;
  try {
    return await action();
  } catch (err) {
    showError(errorEl, err);
    return undefined;
  } finally {
    if (button) button.disabled = false;
  }
}

/**
 * A two-tap button for consequential actions (arm, then confirm within 4 s): touch-friendly and never a
 * blocking `confirm()` dialog.
 */
export function armedButton(props, label, confirmLabel, action) {
  let armedUntil = 0;
  let timer = null;
  const btn = h("button", { type: "button", ...props, text: label });
  btn.addEventListener("click", () => {
    const now = performance.now();
    if (now > armedUntil) {
      armedUntil = now + 4000;
      btn.textContent = confirmLabel;
      btn.classList.add("armed");
      clearTimeout(timer);
      timer = setTimeout(() => {
        btn.textContent = label;
        btn.classList.remove("armed");
      }, 4000);
      return;
    }
    armedUntil = 0;
    clearTimeout(timer);
    btn.textContent = label;
    btn.classList.remove("armed");
    action();
  });
  return btn;
}

/** A labelled field: `<label>` wrapping a caption and the control, with an optional hint. */
export function field(caption, control, hint) {
  return h("label", { class: "field" }, h("span", { class: "caption", text: caption }), control,
    hint ? h("span", { class: "hint", text: hint }) : null);
}

/** An error message element (hidden until used) announced to screen readers. */
export function errorBox(testid) {
  return h("p", { class: "error", role: "alert", "data-testid": testid, hidden: true });
}
