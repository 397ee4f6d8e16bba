// REST and websocket helpers for the gaitscope server (docs/api.md). Every body and message follows
// sessions/schema.py; this module does no rendering, only transport and plain-words errors.

/** A refused request: HTTP status, the server's `detail`, and a sentence a clinician can read. */
export class ApiError extends Error {
  constructor(status, detail, message) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.detail = detail;
    /** @type {boolean | undefined} an upload the server kept, that a retry can resume (upload.js) */
    this.recoverable = undefined;
    /** @type {number | null | undefined} the trial a file uploaded before was stored as (upload.js) */
    this.duplicateOf = undefined;
  }
}

const _STATUS_WORDS = {
  400: "The request was not understood",
  401: "Not logged in",
  403: "Not allowed",
  404: "Not found",
  409: "Refused",
  413: "Too large",
  422: "Not accepted",
  500: "The server failed",
  503: "The server is busy",
};

/** FastAPI's `detail` (a string, or pydantic's list of {loc, msg}) as one readable sentence. */
export function describeDetail(detail) {
  if (detail == null) return "";
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail)) {
    return detail
      .map((d) => {
        if (typeof d === "string") return d;
        const loc = (d.loc || []).filter((p) => p !== "body" && p !== "query" && p !== "path");
        const where = loc.length ? `${loc.join(".")}: ` : "";
        return `${where}${d.msg || JSON.stringify(d)}`;
      })
      .join("; ");
  }
  if (typeof detail === "object" && detail.message) return String(detail.message);
  return JSON.stringify(detail);
}

/** The plain-words message of a failed request (ApiError) or of a network failure. */
export function errorText(err) {
  if (err instanceof ApiError) return err.message;
  if (err instanceof TypeError) return "Could not reach the gaitscope server (network error).";
  return String((err && err.message) || err);
}

// --- the login: CSRF token and "log in first" ---------------------------------------------------------------
// The server wants the login's CSRF token (Me.csrf_token, from auth.js) back in `X-CSRF-Token` with every
// request that is not GET/HEAD/OPTIONS, and answers 401 when nobody is logged in (accounts on). Both rules live
// here, below every fetch of the dashboard, so that no view can forget them.

let _csrfToken = null;
const _SAFE_METHODS = new Set(["GET", "HEAD", "OPTIONS"]);
// Paths whose 401 is an answer for the page to show, not "go and log in": a wrong password, a login check.
const _NO_LOGIN_REDIRECT = new Set(["/api/auth/login", "/api/auth/me"]);

/** Remembers the login's CSRF token (null: accounts off, or logged out). */
export function setCsrfToken(token) {
  _csrfToken = token || null;
}

/** The headers a request with `method` needs besides its own: the CSRF token on state-changing ones. */
export function authHeaders(method) {
  return _csrfToken && !_SAFE_METHODS.has(String(method).toUpperCase()) ? { "X-CSRF-Token": _csrfToken } : {};
}

/** The login page's address, remembering where the user was (to come back there after logging in). */
export function loginHash(from = location.hash) {
  const here = from && !from.startsWith("#/login") ? from : "";
  return here && here !== "#/" ? `#/login?next=${encodeURIComponent(here)}` : "#/login";
}

let _loggedOut = () => {};
/** What to do when the server says the login ended (auth.js forgets the user). */
export function whenLoggedOut(fn) {
  _loggedOut = fn;
}

/** A 401 from the server: the login ended (or never was); off to the login page, coming back here after. */
export function onUnauthorized(path) {
  if (_NO_LOGIN_REDIRECT.has(path.split("?")[0])) return;
  setCsrfToken(null);
  _loggedOut();
  if (!location.hash.startsWith("#/login")) location.hash = loginHash();
}

/** `fetch` with the login's rules: the CSRF header on state-changing requests, a 401 sends to the login page. */
export async function authFetch(path, init = {}) {
  const method = init.method || "GET";
  const resp = await fetch(path, { ...init, headers: { ...(init.headers || {}), ...authHeaders(method) } });
  if (resp.status === 401) onUnauthorized(path);
  return resp;
}

async function _raise(resp) {
  let detail = null;
  try {
    const body = await resp.json();
    detail = body && "detail" in body ? body.detail : body;
  } catch {
    detail = resp.statusText;
  }
  const words = _STATUS_WORDS[resp.status] || `Error ${resp.status}`;
  const text = describeDetail(detail);
  throw new ApiError(resp.status, detail, text ? `${words}: ${text}` : `${words}.`);
}

/**
 * Calls a REST endpoint and returns its JSON (null for 204).
 * @param {string} method
 * @param {string} path e.g. "/api/sessions"
 * @param {object} [body] sent as JSON
 */
export async function api(method, path, body) {
  const init = { method, headers: { Accept: "application/json" } };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const resp = await authFetch(path, init);
  if (!resp.ok) await _raise(resp);
  if (resp.status === 204) return null;
  return resp.json();
}

/**
 * Sends raw bytes (`application/octet-stream`, e.g. an upload's chunk) and returns the JSON answer.
 * @param {string} method
 * @param {string} path
 * @param {Blob} blob
 */
export async function apiBytes(method, path, blob) {
  const resp = await authFetch(path, {
    method,
    headers: { "Content-Type": "application/octet-stream", Accept: "application/json" },
    body: blob,
  });
  if (!resp.ok) await _raise(resp);
  return resp.json();
}

/** Query string from an object, skipping null/undefined values. */
export function query(params) {
  const q = new URLSearchParams();
  for (const [k, v] of Object.entries(params)) if (v !== null && v !== undefined) q.set(k, String(v));
  const s = q.toString();
  return s ? `?${s}` : "";
}

// Close codes after which reconnecting cannot help: policy violation and the 4xxx application codes
// (the server closes with 4404-style codes for an unknown session).
function _isFinalClose(code) {
  return code === 1008 || (code >= 4000 && code < 5000);
}

/**
 * A live session stream that reconnects with exponential backoff (0.5 s doubling to 10 s, reset after a
 * `hello`). Closed by the server with 1013 (this client fell behind) it reconnects like any other drop.
 *
 * @param {number} sessionId
 * @param {{onMessage: (msg: import("./wire.js").BrowserMessage) => void, onStatus?: (status: string, info?: object) => void}} handlers
 *   status is "connecting", "open", "reconnecting" (info.delayMs, info.code) or "closed" (info.code).
 * @param {{maxRateHz?: number, batchMs?: number}} [opts]
 * @returns {{close: () => void}}
 */
export function openSessionStream(sessionId, handlers, opts = {}) {
  const maxRate = opts.maxRateHz ?? 60;
  const batchMs = opts.batchMs ?? 33;
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const url = `${proto}//${location.host}/ws/sessions/${sessionId}?max_rate_hz=${maxRate}&batch_ms=${batchMs}`;
  const status = handlers.onStatus || (() => {});
  let ws = null;
  let delay = 500;
  let timer = null;
  let stopped = false;

  function connect() {
    if (stopped) return;
    status("connecting");
    ws = new WebSocket(url);
    ws.onmessage = (ev) => {
      let msg;
      try {
        msg = JSON.parse(ev.data);
      } catch {
        return; // not JSON: ignore rather than break the stream
      }
      if (msg.type === "hello") {
        delay = 500;
        status("open");
      }
      handlers.onMessage(msg);
    };
    ws.onclose = (ev) => {
      ws = null;
      if (stopped) return;
      if (_isFinalClose(ev.code)) {
        status("closed", { code: ev.code, reason: ev.reason });
        return;
      }
      status("reconnecting", { delayMs: delay, code: ev.code });
      timer = setTimeout(connect, delay);
      delay = Math.min(delay * 2, 10000);
    };
  }

  connect();
  return {
    close() {
      stopped = true;
      clearTimeout(timer);
      if (ws) ws.close(1000, "view closed");
    },
  };
}
