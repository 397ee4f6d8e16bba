// Exports of a session or of one trial (PDF report, CSV of estimates): `POST /api/sessions/{id}/exports` (or
// `POST /api/trials/{id}/exports`, from the review page) starts a job on the server, its progress is polled
// (`GET /api/exports/{id}`) and shown, and the file is downloaded when it is done. A job that takes more than a
// second shows a progress bar with what it is doing.

import * as api from "./api_client.js";
import { fence } from "./auth.js";
import { errorBox, h, runAction } from "./ui.js";

const POLL_MS = 250;
const SHOW_AFTER_MS = 1000; // quicker exports just download: no bar flashing by
const TIMEOUT_MS = 5 * 60 * 1000;
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/**
 * The export card: one button per kind, one progress bar, one error line; of a session, or of one trial of it
 * (`trialId`: the review page's).
 * @param {number | null} sessionId
 * @param {{trialId?: number | null}} [opts]
 * @returns {{el: HTMLElement, stop: () => void}}
 */
export function exportCard(sessionId, { trialId = null } = {}) {
  const what = trialId === null ? "session" : "trial";
  let alive = true;
  const fill = h("div", { class: "meter-fill" });
  const bar = h("div", { class: "meter", role: "progressbar", "aria-label": "Export progress", "aria-valuemin": 0, "aria-valuemax": 100,
    "data-testid": "export-progress" }, fill);
  const step = h("span", { class: "hint", "data-testid": "export-step", "aria-live": "polite" });
  const progress = h("div", { class: "export-progress", hidden: true }, bar, step);
  const done = h("p", { class: "ok", role: "status", "data-testid": "export-done" });
  const error = errorBox("export-error");
  const buttons = [
    ["pdf", `Download the ${what}'s PDF report`, "export-pdf"],
    ["csv", `Download the ${what}'s estimates (CSV)`, "export-csv"],
  ].map(([kind, label, testid]) => {
    const btn = h("button", { type: "button", class: kind === "pdf" ? "primary" : "", "data-testid": testid, text: label });
    btn.addEventListener("click", () => {
      for (const b of buttons) b.disabled = true;
      runAction(btn, error, () => run(kind)).finally(() => {
        for (const b of buttons) b.disabled = false;
      });
    });
    return btn;
  });

  function show(job) {
    const pct = Math.round(100 * job.progress);
    fill.style.width = `${pct}%`;
    bar.setAttribute("aria-valuenow", String(pct));
    step.textContent = `${pct} % · ${job.step}`;
  }

  async function run(kind) {
    done.textContent = "";
    const t0 = performance.now();
    let job = trialId === null ? await api.startExport(sessionId, { kind }) : await api.startTrialExport(trialId, { kind });
    while (job.state === "running") {
      if (!alive) return;
      if (performance.now() - t0 > TIMEOUT_MS) throw new Error("The export took more than 5 minutes: try again, or ask for the server to be checked.");
      if (performance.now() - t0 > SHOW_AFTER_MS) {
        progress.hidden = false;
        show(job);
      }
      await sleep(POLL_MS);
      job = await api.getExport(job.id);
    }
    progress.hidden = true;
    if (job.state === "failed") throw new Error(`The ${kind === "pdf" ? "report" : "CSV"} could not be made: ${job.error}`);
    const href = api.exportFileUrl(job.id);
    const link = h("a", { href, download: job.filename, "data-testid": `export-link-${kind}`, text: job.filename });
    done.replaceChildren(`Ready: `, link, ` (${((performance.now() - t0) / 1000).toFixed(1)} s).`);
    link.click();
  }

  const el = h("section", { class: "card people-export", "data-testid": trialId === null ? "export-card" : "trial-export-card" },
    h("h2", { text: trialId === null ? "Take it away" : "This trial, to take away" }),
    h("p", { class: "hint", text: trialId === null
      ? "The report holds this page's figures and tables; the CSV every estimate, one row per sample (phases in %)."
      : "The trial's own report (its strides, conditions, settings and events) and its estimates, one row per sample (phases in %)." }),
    h("div", { class: "buttons" }, ...buttons), progress, done, error);
  fence(el, "run"); // an export is made on the server: a viewer reads the page instead
  return { el, stop() { alive = false; } };
}
