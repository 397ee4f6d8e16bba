// Chunked upload of a recording (.mcap / .csv / .parquet / .c3d): create, PUT chunks in order, finish -> Trial.
// "Preview" sends the chunks and asks the server what an import would read (upload_preview.js draws it: channels,
// sparklines, what the file feeds, the problem, the channel mapping to edit); "Import" then finishes the upload with
// the mapping previewed and shows the trial and its report. "Upload and import" finishes at once, as before.
// A refusal is shown in the user's terms (which file, row and column, what is wrong); a recording that was never
// finished (cut off by a crash) is refused as recoverable, and a button sends it again to be recovered. A file
// uploaded before (the same content) is refused naming its trial, with a link to it and a button that sends it
// again to keep a second copy.

import { ApiError, authFetch, describeDetail } from "./api.js";
import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { errorBox, field, h, runAction, showError, ValidationError } from "./ui.js";
import { ImportPreviewPanel, reportView } from "./upload_preview.js";

const NAME_RE = /^[^/\\]+\.(mcap|csv|parquet|c3d)$/i; // UploadCreate.filename: the extension in any case
const ACCEPT = ".mcap,.csv,.parquet,.c3d";
const RETRIES = 3; // per chunk, for network failures and 5xx only
const RECOVERABLE_HEADER = "X-Gaitscope-Recoverable"; // server/routes/uploads.py
const DUPLICATE_HEADER = "X-Gaitscope-Duplicate-Of"; // server/routes/uploads.py: the trial it was uploaded as
const RECOVERABLE_RE = /can recover it/; // a preview's problem for an MCAP never finished (sessions/formats/mcap_io.py)

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
 * `POST /api/uploads/{id}/finish` (with ImportOptions `options`, when given): the ImportedTrial, or an ApiError with
 * `recoverable` and `duplicateOf` (the trial a file uploaded before is) set from the server's headers.
 * @param {string} id
 * @param {boolean} recover
 * @param {boolean} keepCopy
 * @param {{mapping: string | null, allow_other_rig: boolean} | null} [options]
 */
async function _finish(id, recover, keepCopy, options = null) {
  const params = { ...(recover ? { recover: true } : {}), ...(keepCopy ? { keep_copy: true } : {}) };
  const init = { method: "POST", headers: { Accept: "application/json" } };
  if (options) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(options);
  }
  const resp = await authFetch(api.finishUploadUrl(id, params), init);
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

/** A refusal of the preview (an ApiError), in the words a refused finish uses. */
function _previewRefused(err) {
  if (!(err instanceof ApiError)) return err;
  const words = err.status === 422 ? "The file was not accepted" : `The preview failed (error ${err.status})`;
  return new ApiError(err.status, err.detail, `${words}: ${refusalText(err.detail)}`);
}

/**
 * How an upload is finished, and what to offer when it is refused: `options` the ImportOptions (the mapping
 * previewed), `show` to show the trial and its report here rather than open it.
 * @typedef {{file: File, subjectId: number, recover: boolean, keepCopy: boolean,
 *   options: {mapping: string | null, allow_other_rig: boolean} | null, show: boolean}} Job
 */

/** The offers a refused upload may get: to recover a recording never finished, to keep a second copy. */
class RefusalOffers {
  constructor() {
    /** @type {Job | null} the recoverable file refused last */
    this.pending = null;
    /** @type {Job | null} the file refused last as uploaded before */
    this.duplicate = null;
    this.recoverBtn = h("button", { type: "button", class: "primary", "data-testid": "upload-recover", text: "Recover this recording" });
    this.recoverBox = h("div", { class: "upload-recover", "data-testid": "upload-recover-box", hidden: true },
      h("p", { class: "hint", text: "Recovering keeps everything recorded up to where the file was cut off (the last second or so may be lost) and stores it as a new trial." }),
      this.recoverBtn);
    this.dupLink = h("a", { "data-testid": "upload-duplicate-link" });
    this.copyBtn = h("button", { type: "button", "data-testid": "upload-keep-copy", text: "Upload a second copy anyway" });
    this.dupBox = h("div", { class: "upload-recover", "data-testid": "upload-duplicate-box", hidden: true },
      h("p", { class: "hint" }, "This file is already stored: ", this.dupLink, ". Nothing was stored again."), this.copyBtn);
  }

  /** Hides both offers. */
  hide() {
    this.pending = null;
    this.duplicate = null;
    this.recoverBox.hidden = true;
    this.dupBox.hidden = true;
  }

  /** Offers to send `job` again to be recovered. @param {Job} job */
  offerRecovery(job) {
    this.pending = job;
    this.recoverBox.hidden = false;
  }

  /** Offers to keep a second copy of `job`'s file, stored before as trial `trialId`. @param {Job} job */
  offerCopy(job, trialId) {
    this.duplicate = job;
    this.dupLink.href = `#/trials/${trialId}`;
    this.dupLink.textContent = `trial ${trialId}`;
    this.dupBox.hidden = false;
  }
}

/** Shows in `box` the trial an import made, with a link to its review and what the import read. */
function _showImported(box, trial) {
  box.replaceChildren(
    h("p", { class: "ok", "data-testid": "upload-imported-text",
      text: `Stored as trial ${trial.id}: ${trial.name}, ${trial.samples} samples.` }),
    h("p", {}, h("a", { href: `#/trials/${trial.id}`, "data-testid": "upload-trial-link", text: `Open trial ${trial.id} in review` })),
    trial.report ? reportView(trial.report) : null);
  box.hidden = false;
}

/**
 * Creates an upload and sends its chunks in order; its id. A failure deletes it (it holds no space).
 * `ui`: the progress bar and text to update, and whether the person cancelled.
 * @param {File} f
 * @param {number} subjectId
 * @param {boolean} recover
 * @param {{progress: HTMLProgressElement, progressText: HTMLElement, cancelled: () => boolean}} ui
 */
async function _sendChunks(f, subjectId, recover, ui) {
  const { progress, progressText } = ui;
  progress.value = 0;
  progressText.textContent = recover ? "sending it again to recover it…" : "starting…";
  const up = await api.createUpload({ filename: f.name, size: f.size, subject_id: subjectId });
  let offset = up.received || 0;
  const chunk = Math.max(1, up.chunk_size);
  try {
    while (offset < f.size) {
      if (ui.cancelled()) throw new ValidationError("Upload cancelled.");
      const res = await _putWithRetry(up.id, offset, f.slice(offset, Math.min(offset + chunk, f.size)));
      offset = res.received;
      progress.value = offset / f.size;
      progressText.textContent = `${Math.round((100 * offset) / f.size)} % (${offset} of ${f.size} bytes)`;
    }
  } catch (err) {
    progressText.textContent = "not stored";
    api.cancelUpload(up.id).catch(() => {});
    throw err;
  }
  return up.id;
}

/** The upload form's elements (the offers and the preview panel placed in it), fenced to the upload role. */
function _uploadForm(subjectSelect, /** @type {RefusalOffers} */ offers, /** @type {ImportPreviewPanel} */ panel) {
  const file = h("input", { type: "file", id: "upload-file", "data-testid": "upload-file", accept: ACCEPT });
  const progress = h("progress", { id: "upload-progress", "data-testid": "upload-progress", max: 1, value: 0 });
  const progressText = h("span", { class: "hint", "data-testid": "upload-progress-text", "aria-live": "polite" });
  const previewBtn = h("button", { type: "button", class: "primary", "data-testid": "upload-preview-submit", text: "Preview" });
  const submit = h("button", { type: "submit", "data-testid": "upload-submit", text: "Upload and import" });
  const cancel = h("button", { type: "button", "data-testid": "upload-cancel", text: "Cancel", disabled: true });
  const error = errorBox("upload-error");
  const imported = h("div", { class: "upload-imported", "data-testid": "upload-imported", hidden: true });
  const form = h("form", { class: "card form upload-form", "data-testid": "upload-form", novalidate: true },
    h("h2", { text: "Upload a recording" }),
    field("File", file, ".mcap (gaitscope's or another tool's), replay .csv, LocoHub .parquet or motion capture .c3d"),
    field("Subject", subjectSelect),
    h("div", { class: "progress-row" }, progress, progressText),
    h("div", { class: "buttons" }, previewBtn, submit, cancel),
    h("p", { class: "hint", text: "Preview shows what an import would read (channels, what they feed, the channel mapping) before anything is stored." }),
    error, offers.recoverBox, offers.dupBox, panel.el, imported);
  fence(form, "upload");
  return { form, file, progress, progressText, previewBtn, submit, cancel, error, imported };
}

/** The upload form; `subjectSelect` is filled by the sessions page. Returns {el, unmount}. */
export function mountUpload(subjectSelect) {
  let cancelled = false;
  let previewing = null; // the upload previewed, still open on the server: {id, file, subjectId}
  const offers = new RefusalOffers();
  const panel = new ImportPreviewPanel(refusalText);
  const { form, file, progress, progressText, previewBtn, submit, cancel, error, imported } =
    _uploadForm(subjectSelect, offers, panel);

  cancel.addEventListener("click", () => {
    cancelled = true;
  });

  /**
   * Runs `action` on `button` (its errors in `box`) with `others` disabled meanwhile; `cancellable`: the
   * Cancel button works during it.
   */
  function busy(button, box, others, cancellable, action) {
    cancelled = false;
    if (cancellable) cancel.disabled = false;
    for (const b of others) b.disabled = true;
    return runAction(button, box, action).finally(() => {
      cancel.disabled = true;
      for (const b of others) b.disabled = false;
    });
  }

  /** Drops the upload previewed (the server deletes its bytes) and its preview. */
  function discardPreview() {
    if (previewing) api.cancelUpload(previewing.id).catch(() => {});
    previewing = null;
    panel.clear();
    form.classList.remove("previewing");
  }

  /** Clears what the last action left: offers, the preview, the trial imported. */
  function reset() {
    offers.hide();
    discardPreview();
    imported.hidden = true;
  }

  /** The file and subject chosen, checked as the server would. */
  function chosen() {
    const f = file.files && file.files[0];
    if (!f) throw new ValidationError("Choose a file to upload.");
    if (!NAME_RE.test(f.name) || f.name.length > 200) {
      throw new ValidationError("The file must be a .mcap, .csv, .parquet or .c3d file (name up to 200 characters).");
    }
    if (f.size < 1) throw new ValidationError("The file is empty.");
    const subjectId = Number(subjectSelect.value);
    if (!subjectId) throw new ValidationError("Choose the subject this recording belongs to.");
    return { f, subjectId };
  }

  const sendChunks = (f, subjectId, recover) =>
    _sendChunks(f, subjectId, recover, { progress, progressText, cancelled: () => cancelled });

  /** Finishes a sent upload (from here the server owns it: a refused finish stores nothing and drops it). */
  async function finishAs(id, /** @type {Job} */ job) {
    try {
      const trial = await _finish(id, job.recover, job.keepCopy, job.options);
      progressText.textContent = `stored as trial ${trial.id}${job.recover ? " (recovered)" : job.keepCopy ? " (a second copy)" : ""}`;
      if (job.show) _showImported(imported, trial);
      else location.hash = `#/trials/${trial.id}`;
      return trial;
    } catch (err) {
      progressText.textContent = "not stored";
      if (err.recoverable && !job.recover) offers.offerRecovery(job);
      if (err.duplicateOf && !job.keepCopy) {
        progressText.textContent = `already uploaded as trial ${err.duplicateOf}`;
        offers.offerCopy(job, err.duplicateOf);
      }
      throw err;
    }
  }

  /** Sends a file and finishes it. */
  async function send(/** @type {Job} */ job) {
    const id = await sendChunks(job.file, job.subjectId, job.recover);
    progressText.textContent = job.recover ? "recovering the recording and checking it…" : "checking the file…";
    return finishAs(id, job);
  }

  /** Previews the open upload with `mapping` (JSON text; null: the saved or suggested one). */
  async function previewWith(mapping) {
    const { id, file: f, subjectId } = previewing;
    const p = await api.previewUpload(id, { mapping, allow_other_rig: panel.otherRig.checked });
    if (!previewing || previewing.id !== id) return; // discarded meanwhile
    panel.show(p);
    form.classList.add("previewing");
    progressText.textContent = p.problem ? "previewed: it cannot be imported as it is" : "previewed: nothing is stored yet";
    if (p.problem && RECOVERABLE_RE.test(p.problem)) { // a recording never finished: offer to recover it
      offers.offerRecovery({ file: f, subjectId, recover: false, keepCopy: false, options: null, show: true });
    }
  }

  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    reset();
    busy(submit, error, [previewBtn], true, async () => {
      const { f, subjectId } = chosen();
      await send({ file: f, subjectId, recover: false, keepCopy: false, options: null, show: false });
    });
  });

  previewBtn.addEventListener("click", () => {
    reset();
    busy(previewBtn, error, [submit], true, async () => {
      const { f, subjectId } = chosen();
      const id = await sendChunks(f, subjectId, false);
      previewing = { id, file: f, subjectId };
      progressText.textContent = "reading the file…";
      try {
        await previewWith(null);
      } catch (err) {
        discardPreview();
        progressText.textContent = "not stored";
        throw _previewRefused(err);
      }
    });
  });

  panel.applyBtn.addEventListener("click", () => {
    panel.importBtn.disabled = true;
    runAction(panel.applyBtn, panel.error, async () => {
      if (!previewing) throw new ValidationError("The upload has ended: preview the file again.");
      const mapping = panel.mappingText();
      progressText.textContent = "reading the file with this mapping…";
      try {
        await previewWith(mapping);
      } catch (err) {
        progressText.textContent = "previewed: the mapping was not accepted";
        throw _previewRefused(err);
      }
    }).finally(() => panel.refresh());
  });

  panel.importBtn.addEventListener("click", () => {
    if (!previewing) return;
    const { id, file: f, subjectId } = previewing;
    const options = panel.options();
    previewing = null; // the finish ends the upload, whatever its outcome
    progressText.textContent = "importing…";
    busy(panel.importBtn, error, [submit, previewBtn], false, async () => {
      try {
        await finishAs(id, { file: f, subjectId, recover: false, keepCopy: false, options, show: true });
      } finally {
        discardPreview();
      }
    });
  });

  panel.discardBtn.addEventListener("click", () => {
    discardPreview();
    progressText.textContent = "discarded: nothing was stored";
  });

  offers.recoverBtn.addEventListener("click", () => {
    if (!offers.pending) return;
    const job = { ...offers.pending, recover: true };
    discardPreview(); // sent again, to be recovered
    busy(offers.recoverBtn, error, [submit, previewBtn], true, async () => {
      await send(job);
      offers.hide();
    });
  });

  offers.copyBtn.addEventListener("click", () => {
    if (!offers.duplicate) return;
    const job = { ...offers.duplicate, keepCopy: true };
    busy(offers.copyBtn, error, [submit, previewBtn], true, async () => {
      await send(job);
      offers.hide();
    });
  });

  const changed = () => {
    showError(error, null);
    reset();
    progress.value = 0;
    progressText.textContent = "";
  };
  file.addEventListener("change", changed);
  subjectSelect.addEventListener("change", () => {
    if (previewing) changed(); // the upload previewed belongs to the subject chosen before
  });
  return {
    el: form,
    unmount() {
      cancelled = true;
      discardPreview();
    },
  };
}
