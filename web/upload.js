// Chunked upload of a recording (.mcap / .csv / .parquet): create, PUT chunks in order, finish -> Trial.
// A refusal is shown in the user's terms (which file, row and column, what is wrong); a recording that was never
// finished (cut off by a crash) is refused as recoverable, and a button sends it again to be recovered. A file
// uploaded before (the same content) is refused naming its trial, with a link to it and a button that sends it
// again to keep a second copy.

import { ApiError, authFetch, describeDetail } from "./api.js";
import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { errorBox, field, h, runAction, showError, ValidationError } from "./ui.js";

const NAME_RE = /^[^/\\]+\.(mcap|csv|parquet)$/i; // UploadCreate.filename: the extension in any case
const RETRIES = 3; // per chunk, for network failures and 5xx only
const RECOVERABLE_HEADER = "X-Gaitscope-Recoverable"; // server/routes/uploads.py
const DUPLICATE_HEADER = "X-Gaitscope-Duplicate-Of"; // server/routes/uploads.py: the trial it was uploaded as

const _sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function _putWithRetry(id, offset, blob) {
  for (let attempt = 1; ; attempt++) {
    try {
      return await api.uploadChunk(id, blob, { offset });
    } catch (err) {
      const retriable = !(err instanceof ApiError) || err.status >= 500;
      if (!retriable || attempt >= RETRIES) throw err;
      await _sleep(500 * attempt);
    }
  }
}

/**
 * The server's reason a file was refused, in the user's terms: `file trial.csv, column 'thigh_angle_deg', row 7: x`
 * reads "trial.csv, row 7, column thigh_angle_deg: x".
 */
export function refusalText(detail) {
  const text = describeDetail(detail);
  const m = text.match(/^file (.+?)(?:, column '([^']*)')?(?:, row (\d+))?: (.*)$/s);
  if (!m) return text;
  const [, file, column, row, what] = m;
  const where = [row ? `row ${row}` : null, column ? `column ${column}` : null].filter(Boolean).join(", ");
  return `${file}${where ? `, ${where}` : ""}: ${what}`;
}

/**
 * `POST /api/uploads/{id}/finish`: the Trial, or an ApiError with `recoverable` and `duplicateOf` (the trial a file
 * uploaded before is) set from the server's headers.
 */
async function _finish(id, recover, keepCopy) {
  const params = { ...(recover ? { recover: true } : {}), ...(keepCopy ? { keep_copy: true } : {}) };
  const resp = await authFetch(api.finishUploadUrl(id, params),
    { method: "POST", headers: { Accept: "application/json" } });
  if (resp.ok) return resp.json();
  let detail = resp.statusText;
  try {
    detail = (await resp.json()).detail;
  } catch {
    // not JSON: the status text says enough
  }
  const duplicateOf = Number(resp.headers.get(DUPLICATE_HEADER)) || null;
  const words = resp.status === 422 ? "The file was not accepted"
    : duplicateOf ? "Not stored again" : `The upload failed (error ${resp.status})`;
  const err = new ApiError(resp.status, detail, `${words}: ${refusalText(detail)}`);
  err.recoverable = resp.headers.get(RECOVERABLE_HEADER) === "1";
  err.duplicateOf = duplicateOf;
  throw err;
}

/** The upload form; `subjectSelect` is filled by the sessions page. Returns {el, unmount}. */
export function mountUpload(subjectSelect) {
  let cancelled = false;
  let activeId = null;
  let pending = null; // the recoverable file refused last: {file, subjectId, keepCopy}
  let duplicate = null; // the file refused last as uploaded before: {file, subjectId}
  const file = h("input", { type: "file", id: "upload-file", "data-testid": "upload-file", accept: ".mcap,.csv,.parquet" });
  const progress = h("progress", { id: "upload-progress", "data-testid": "upload-progress", max: 1, value: 0 });
  const progressText = h("span", { class: "hint", "data-testid": "upload-progress-text", "aria-live": "polite" });
  const submit = h("button", { type: "submit", class: "primary", "data-testid": "upload-submit", text: "Upload" });
  const cancel = h("button", { type: "button", "data-testid": "upload-cancel", text: "Cancel", disabled: true });
  const error = errorBox("upload-error");
  const recoverBtn = h("button", { type: "button", class: "primary", "data-testid": "upload-recover", text: "Recover this recording" });
  const recoverBox = h("div", { class: "upload-recover", "data-testid": "upload-recover-box", hidden: true },
    h("p", { class: "hint", text: "Recovering keeps everything recorded up to where the file was cut off (the last second or so may be lost) and stores it as a new trial." }),
    recoverBtn);
  const dupLink = h("a", { "data-testid": "upload-duplicate-link" });
  const copyBtn = h("button", { type: "button", "data-testid": "upload-keep-copy", text: "Upload a second copy anyway" });
  const dupBox = h("div", { class: "upload-recover", "data-testid": "upload-duplicate-box", hidden: true },
    h("p", { class: "hint" }, "This file is already stored: ", dupLink, ". Nothing was stored again."), copyBtn);
  const form = h("form", { class: "card form", "data-testid": "upload-form", novalidate: true },
    h("h2", { text: "Upload a recording" }),
    field("File", file, ".mcap (a gaitscope recording), replay .csv or LocoHub .parquet"),
    field("Subject", subjectSelect),
    h("div", { class: "progress-row" }, progress, progressText),
    h("div", { class: "buttons" }, submit, cancel), error, recoverBox, dupBox);
  fence(form, "upload");

  cancel.addEventListener("click", () => {
    cancelled = true;
  });

  /** Hides the offers to recover a recording and to keep a second copy of a file. */
  function hideOffers() {
    pending = null;
    duplicate = null;
    recoverBox.hidden = true;
    dupBox.hidden = true;
  }

  async function send(f, subjectId, recover, keepCopy = false) {
    progress.value = 0;
    progressText.textContent = recover ? "sending it again to recover it…" : "starting…";
    const up = await api.createUpload({ filename: f.name, size: f.size, subject_id: subjectId });
    activeId = up.id;
    let offset = up.received || 0;
    const chunk = Math.max(1, up.chunk_size);
    try {
      while (offset < f.size) {
        if (cancelled) throw new ValidationError("Upload cancelled.");
        const res = await _putWithRetry(up.id, offset, f.slice(offset, Math.min(offset + chunk, f.size)));
        offset = res.received;
        progress.value = offset / f.size;
        progressText.textContent = `${Math.round((100 * offset) / f.size)} % (${offset} of ${f.size} bytes)`;
      }
      progressText.textContent = recover ? "recovering the recording and checking it…" : "checking the file…";
      activeId = null; // from here the server owns it: a refused finish stores nothing and drops the upload
      const trial = await _finish(up.id, recover, keepCopy);
      progressText.textContent = `stored as trial ${trial.id}${recover ? " (recovered)" : keepCopy ? " (a second copy)" : ""}`;
      location.hash = `#/trials/${trial.id}`;
    } catch (err) {
      progressText.textContent = "not stored";
      // A half-sent upload is deleted so it holds no space on the server.
      if (activeId) api.cancelUpload(activeId).catch(() => {});
      activeId = null;
      if (err.recoverable && !recover) {
        pending = { file: f, subjectId, keepCopy };
        recoverBox.hidden = false;
      }
      if (err.duplicateOf && !keepCopy) {
        progressText.textContent = `already uploaded as trial ${err.duplicateOf}`;
        duplicate = { file: f, subjectId, recover };
        dupLink.href = `#/trials/${err.duplicateOf}`;
        dupLink.textContent = `trial ${err.duplicateOf}`;
        dupBox.hidden = false;
      }
      throw err;
    }
  }

  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    cancelled = false;
    cancel.disabled = false;
    hideOffers();
    runAction(submit, error, async () => {
      const f = file.files && file.files[0];
      if (!f) throw new ValidationError("Choose a file to upload.");
      if (!NAME_RE.test(f.name) || f.name.length > 200) {
        throw new ValidationError("The file must be a .mcap, .csv or .parquet file (name up to 200 characters).");
      }
      if (f.size < 1) throw new ValidationError("The file is empty.");
      const subjectId = Number(subjectSelect.value);
      if (!subjectId) throw new ValidationError("Choose the subject this recording belongs to.");
      await send(f, subjectId, false);
    }).finally(() => {
      cancel.disabled = true;
    });
  });

  recoverBtn.addEventListener("click", () => {
    if (!pending) return;
    const { file: f, subjectId, keepCopy } = pending;
    cancelled = false;
    cancel.disabled = false;
    submit.disabled = true;
    runAction(recoverBtn, error, async () => {
      await send(f, subjectId, true, keepCopy);
      pending = null;
      recoverBox.hidden = true;
    }).finally(() => {
      cancel.disabled = true;
      submit.disabled = false;
    });
  });

  copyBtn.addEventListener("click", () => {
    if (!duplicate) return;
    const { file: f, subjectId, recover } = duplicate;
    cancelled = false;
    cancel.disabled = false;
    submit.disabled = true;
    runAction(copyBtn, error, async () => {
      await send(f, subjectId, recover, true);
      hideOffers();
    }).finally(() => {
      cancel.disabled = true;
      submit.disabled = false;
    });
  });

  file.addEventListener("change", () => {
    showError(error, null);
    hideOffers();
    progress.value = 0;
    progressText.textContent = "";
  });
  return {
    el: form,
    unmount() {
      cancelled = true;
    },
  };
}
