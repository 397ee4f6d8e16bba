// Review notes: a note at the cursor's time or over a span of the trial, saved with it
// (`POST /api/trials/{id}/annotations`), listed by time with the notes taken live while the trial recorded
// (`source` "live": the session's log, not deleted here), deletable by whoever wrote it, and drawn on the plots
// as labelled markers (review_markers.js).

import * as api from "./api_client.js";
import { currentUser, fence, may } from "./auth.js";
import { errorBox, fmt, h, readNumber, runAction, showError, ValidationError } from "./ui.js";

/** Who is acting: the logged-in user (the server writes their name into the note, whatever the body says). */
export function currentActor() {
  const me = currentUser();
  return me ? me.name : "";
}

/**
 * The notes card.
 * @param {number} trialId
 * @param {{cursor: () => (number | null), range: () => (number[] | null), onChange: (notes: object[]) => void,
 *   onSelect: (t: number) => void}} hooks the cursor's time, the trial's time range, and what to do when the
 *   notes change or one is chosen
 */
export function notesCard(trialId, hooks) {
  const st = { notes: [] };
  const text = h("input", { type: "text", id: "note-text", "data-testid": "note-text", maxlength: 500,
    placeholder: "e.g. toe catch, subject stumbles" });
  const spanBox = h("input", { type: "checkbox", id: "note-span", "data-testid": "note-span" });
  const from = h("input", { type: "number", id: "note-from", "data-testid": "note-from", step: 0.01, inputmode: "decimal" });
  const to = h("input", { type: "number", id: "note-to", "data-testid": "note-to", step: 0.01, inputmode: "decimal",
    disabled: true });
  const useCursor = h("button", { type: "button", "data-testid": "note-at-cursor", text: "At the cursor" });
  const add = h("button", { type: "button", class: "primary", "data-testid": "note-add", text: "Add note" });
  const error = errorBox("note-error");
  const list = h("ul", { class: "review-notes", "data-testid": "note-list", "aria-label": "Notes of the trial" });
  const el = h("section", { class: "card", "data-testid": "notes-card" },
    h("h2", { text: "Notes" }),
    h("p", { class: "hint", text: "A note at a time, or over a span, saved with the trial and shown on the plots, "
      + "with the notes taken live during it. Only whoever wrote a note in review may delete it." }),
    h("label", { for: "note-text", class: "caption", text: "Note" }), text,
    h("div", { class: "inline note-times" },
      h("label", {}, "At ", from, " s"),
      h("label", { class: "choice" }, spanBox, h("span", { text: "over a span, to" })),
      h("label", {}, to, " s"), useCursor),
    h("div", { class: "buttons" }, add), error, list);
  fence(el, "annotate");

  spanBox.addEventListener("change", () => {
    to.disabled = !spanBox.checked;
    if (spanBox.checked && to.value === "" && from.value !== "") to.value = (Number(from.value) + 1).toFixed(2);
  });
  function atCursor() {
    const t = hooks.cursor();
    if (t != null) from.value = t.toFixed(2);
  }
  useCursor.addEventListener("click", atCursor);

  function render() {
    const items = st.notes.map((n) => {
      const when = n.t_end == null ? `${fmt(n.t, 2)} s` : `${fmt(n.t, 2)}–${fmt(n.t_end, 2)} s`;
      const go = h("button", { type: "button", class: "link", "data-testid": "note-go", text: when,
        title: "Move the cursor here" });
      go.addEventListener("click", () => hooks.onSelect(n.t));
      const live = n.source === "live";
      const who = h("span", { class: "hint", "data-testid": "note-row-by", text: live ? `by ${n.actor}, taken live` : `by ${n.actor}` });
      if (live) {
        // taken during the session: part of its log, listed here, never deleted from review
        return h("li", { "data-testid": "note-row", "data-id": n.id, "data-source": "live",
          title: "Taken live during the session (in its event log)" }, go, " ",
          h("span", { class: "note-text", "data-testid": "note-row-text", text: n.text }), " ", who);
      }
      const mine = n.actor === currentActor() && may("annotate");
      const del = h("button", { type: "button", class: "small", "data-testid": "note-delete", text: "Delete",
        disabled: !mine, title: mine ? "Delete this note" : `Only ${n.actor} may delete it` });
      const delError = errorBox("note-delete-error");
      del.addEventListener("click", () => runAction(del, delError, async () => {
        await api.deleteAnnotation(trialId, n.id);
        st.notes = st.notes.filter((x) => x !== n);
        changed();
      }));
      return h("li", { "data-testid": "note-row", "data-id": n.id, "data-source": "review" }, go, " ",
        h("span", { class: "note-text", "data-testid": "note-row-text", text: n.text }), " ", who, " ", del, delError);
    });
    list.replaceChildren(...(items.length ? items : [h("li", { class: "hint", text: "No notes yet." })]));
  }
  function changed() {
    render();
    hooks.onChange(st.notes);
  }

  add.addEventListener("click", () => runAction(add, error, async () => {
    const range = hooks.range();
    if (!range) throw new ValidationError("The trial is not loaded yet.");
    const words = text.value.trim();
    if (!words) throw new ValidationError("Write the note first.");
    if (from.value === "") atCursor();
    const lo = +range[0].toFixed(2) - 0.01;
    const hi = +range[1].toFixed(2) + 0.01;
    const t = readNumber(from, { label: "The note's time", min: lo, max: hi });
    const body = { t: Math.max(t, 0), text: words };
    if (spanBox.checked) {
      const tEnd = readNumber(to, { label: "The span's end", min: lo, max: hi });
      if (tEnd <= t) throw new ValidationError("The span must end after it starts.");
      body.t_end = tEnd;
    }
    const note = await api.addAnnotation(trialId, body);
    st.notes = [...st.notes, note].sort((a, b) => a.t - b.t);
    if (text.value.trim() === words) text.value = ""; // not what was typed meanwhile
    showError(error, null);
    changed();
  }));

  return {
    el,
    /** Loads the trial's notes (`GET .../annotations`). */
    async load() {
      st.notes = await api.listAnnotations(trialId);
      changed();
    },
    notes: () => st.notes,
    atCursor,
  };
}
