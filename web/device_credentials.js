// The live page's "Device credentials" card, on a session fed by a device (issue #13): the device's websocket
// (`/ws/devices/{id}`) needs a token of its session. Issue one (`POST /api/sessions/{id}/device-tokens`): the
// token is shown once, with a copy button and a plain warning, and never again (the server keeps only its
// hash); the list (`GET`) shows each token's first characters, who issued it and when, and whether it is
// revoked; revoking (`DELETE …/{token_id}`, two taps) refuses the next connection with it and disconnects a
// device using it.

import * as api from "./api_client.js";
import { fence, may } from "./auth.js";
import { armedButton, errorBox, fmtUtc, h, runAction, showError } from "./ui.js";

/**
 * @param {number} sessionId
 * @returns {{el: HTMLElement, setSession: (s: object) => void}}
 */
export function deviceCredentialsCard(sessionId) {
  const issueBtn = h("button", { type: "button", class: "primary", "data-testid": "token-issue", text: "Issue a device token" });
  const error = errorBox("token-error");
  const tokenText = h("code", { class: "token-value", "data-testid": "token-value" });
  const copyBtn = h("button", { type: "button", "data-testid": "token-copy", text: "Copy" });
  const copied = h("span", { class: "ok", role: "status", "data-testid": "token-copied" });
  const doneBtn = h("button", { type: "button", "data-testid": "token-hide", text: "I have copied it" });
  const fresh = h("div", { class: "token-fresh", role: "alert", "data-testid": "token-fresh", hidden: true },
    h("p", { class: "token-warning", "data-testid": "token-warning",
      text: "Copy this token into the device now: it will not be shown again. Anyone holding it can stream to this session." }),
    h("div", { class: "inline" }, tokenText, copyBtn, doneBtn), copied);
  const list = h("ul", { class: "token-list", "data-testid": "token-list" });
  const tools = h("div", {}, h("div", { class: "buttons" }, issueBtn), fresh, error);
  const el = h("section", { class: "card", "data-testid": "device-credentials-card", hidden: true },
    h("h2", { text: "Device credentials" }),
    h("p", { class: "hint", text: "The device connects with a token of this session (Authorization: Bearer, or ?token=). "
      + "Revoke a token when a device is lost or replaced." }),
    fence(tools, "run"), list);

  function row(t) {
    const state = t.revoked_utc ? `revoked ${fmtUtc(t.revoked_utc)} by ${t.revoked_by}` : "in use";
    const rowError = errorBox("token-revoke-error");
    const revoke = t.revoked_utc ? null : armedButton({ class: "danger small", "data-testid": "token-revoke" }, "Revoke",
      "Tap again to revoke", () => runAction(revoke, rowError, async () => {
        await api.revokeToken(sessionId, t.id);
        await load();
      }));
    const li = h("li", { "data-testid": "token-row", "data-id": t.id, "data-revoked": t.revoked_utc ? "true" : "false" },
      h("code", { "data-testid": "token-prefix", text: `${t.prefix}…` }), " ",
      h("span", { class: "hint", text: `issued ${fmtUtc(t.created_utc)} by ${t.created_by}` }), " ",
      h("span", { class: t.revoked_utc ? "token-revoked" : "token-live", "data-testid": "token-state", text: state }), " ",
      revoke && may("run") ? revoke : null, rowError);
    return li;
  }

  async function load() {
    try {
      const tokens = await api.listTokens(sessionId);
      list.replaceChildren(...(tokens.length ? tokens.map(row)
        : [h("li", { class: "hint", "data-testid": "token-none", text: "No token yet: the device cannot connect until one is issued." })]));
    } catch (err) {
      showError(error, err);
    }
  }

  issueBtn.addEventListener("click", () => runAction(issueBtn, error, async () => {
    const t = await api.issueToken(sessionId);
    tokenText.textContent = t.token;
    copied.textContent = "";
    fresh.hidden = false;
    await load();
  }));
  copyBtn.addEventListener("click", async () => {
    try {
      await navigator.clipboard.writeText(tokenText.textContent);
      copied.textContent = "Copied.";
    } catch {
      // no clipboard (plain http on another host): select the text for a manual copy
      const range = document.createRange();
      range.selectNodeContents(tokenText);
      const sel = window.getSelection();
      sel.removeAllRanges();
      sel.addRange(range);
      copied.textContent = "Select and copy it by hand (the browser refused the clipboard).";
    }
  });
  doneBtn.addEventListener("click", () => {
    tokenText.textContent = "";
    fresh.hidden = true;
  });

  let loaded = false;
  return {
    el,
    /** A `Session`: the card shows only on a device session, and loads its tokens once. */
    setSession(s) {
      el.hidden = s.source.kind !== "device";
      if (!el.hidden && !loaded) {
        loaded = true;
        load();
      }
    },
  };
}
