// Chunked upload of a recording (.mcap / .csv / .parquet): create, PUT chunks in order, finish -> Trial.

import { api, ApiError, putChunk } from "./api.js";
import { errorBox, field, h, runAction, showError, ValidationError } from "./ui.js";

const NAME_RE = /^[^/\\]+\.(mcap|csv|parquet)$/; // UploadCreate.filename
const RETRIES = 3; // per chunk, for network failures and 5xx only

const _sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function _putWithRetry(id, offset, blob) {
  for (let attempt = 1; ; attempt++) {
    try {
      return await putChunk(id, offset, blob);
    } catch (err) {
      const retriable = !(err instanceof ApiError) || err.status >= 500;
      if (!retriable || attempt >= RETRIES) throw err;
      await _sleep(500 * attempt);
    }
  }
}

/** The upload form; `subjectSelect` is filled by the sessions page. Returns {el, unmount}. */
export function mountUpload(subjectSelect) {
  let cancelled = false;
  let activeId = null;
  const file = h("input", { type: "file", id: "upload-file", "data-testid": "upload-file", accept: ".mcap,.csv,.parquet" });
  const progress = h("progress", { id: "upload-progress", "data-testid": "upload-progress", max: 1, value: 0 });
  const progressText = h("span", { class: "hint", "data-testid": "upload-progress-text", "aria-live": "polite" });
  const submit = h("button", { type: "submit", class: "primary", "data-testid": "upload-submit", text: "Upload" });
  const cancel = h("button", { type: "button", "data-testid": "upload-cancel", text: "Cancel", disabled: true });
  const error = errorBox("upload-error");
  const form = h("form", { class: "card form", "data-testid": "upload-form", novalidate: true },
    h("h2", { text: "Upload a recording" }),
    field("File", file, ".mcap (finished, indexed), replay .csv or LocoHub .parquet"),
    field("Subject", subjectSelect),
    h("div", { class: "progress-row" }, progress, progressText),
    h("div", { class: "buttons" }, submit, cancel), error);

  cancel.addEventListener("click", () => {
    cancelled = true;
  });

  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    cancelled = false;
    cancel.disabled = false;
    runAction(submit, error, async () => {
      const f = file.files && file.files[0];
      if (!f) throw new ValidationError("Choose a file to upload.");
      if (!NAME_RE.test(f.name) || f.name.length > 200) {
        throw new ValidationError("The file must be a .mcap, .csv or .parquet file (name up to 200 characters).");
      }
      if (f.size < 1) throw new ValidationError("The file is empty.");
      const subjectId = Number(subjectSelect.value);
      if (!subjectId) throw new ValidationError("Choose the subject this recording belongs to.");
      progress.value = 0;
      progressText.textContent = "starting…";
      const up = await api("POST", "/api/uploads", { filename: f.name, size: f.size, subject_id: subjectId });
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
        progressText.textContent = "checking the file…";
        activeId = null; // from here the server owns it: a refused finish stores nothing and drops the upload
        const trial = await api("POST", `/api/uploads/${encodeURIComponent(up.id)}/finish`);
        progressText.textContent = `stored as trial ${trial.id}`;
        location.hash = `#/trials/${trial.id}`;
      } catch (err) {
        progressText.textContent = "not stored";
        // A half-sent upload is deleted so it holds no space on the server.
        if (activeId) api("DELETE", `/api/uploads/${encodeURIComponent(activeId)}`).catch(() => {});
        activeId = null;
        if (err instanceof ApiError && err.status === 422) {
          throw new ApiError(err.status, err.detail, `The file was not accepted: ${err.message.replace(/^Not accepted: /, "")}`);
        }
        throw err;
      }
    }).finally(() => {
      cancel.disabled = true;
    });
  });
  file.addEventListener("change", () => {
    showError(error, null);
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
