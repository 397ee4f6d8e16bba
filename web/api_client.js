// GENERATED from the app's OpenAPI document (gaitscope.server.app.create_app().openapi()) by
// `gaitscope api-client --out web/api_client.js`: do not edit by hand. Change the routes and run the command
// again; tests/server/test_api_client.py fails while this file differs from what they generate.
//
// One function per REST operation (its path parameters, then its body, then its query parameters as one
// object), each returning the operation's JSON answer (null for 204), and one `<name>Url` per operation: its
// address. Errors are web/api.js's ApiError.

import { api, apiBytes, query } from "./api.js";

/** @typedef {import("./wire.js").AnnotationCreate} AnnotationCreate */
/** @typedef {import("./wire.js").AssistanceLimits} AssistanceLimits */
/** @typedef {import("./wire.js").AuditEntry} AuditEntry */
/** @typedef {import("./wire.js").AuditVerification} AuditVerification */
/** @typedef {import("./wire.js").CalibrationRequest} CalibrationRequest */
/** @typedef {import("./wire.js").ClusterNode} ClusterNode */
/** @typedef {import("./wire.js").CompareRequest} CompareRequest */
/** @typedef {import("./wire.js").Comparison} Comparison */
/** @typedef {import("./wire.js").DeviceToken} DeviceToken */
/** @typedef {import("./wire.js").Event} Event */
/** @typedef {import("./wire.js").ExportCreate} ExportCreate */
/** @typedef {import("./wire.js").ExportJob} ExportJob */
/** @typedef {import("./wire.js").Fingerprints} Fingerprints */
/** @typedef {import("./wire.js").GPLearningControl} GPLearningControl */
/** @typedef {import("./wire.js").GPLearningState} GPLearningState */
/** @typedef {import("./wire.js").ImuCalibration} ImuCalibration */
/** @typedef {import("./wire.js").ImuCalibrationRequest} ImuCalibrationRequest */
/** @typedef {import("./wire.js").ImuCalibrationStatus} ImuCalibrationStatus */
/** @typedef {import("./wire.js").IntentSeries} IntentSeries */
/** @typedef {import("./wire.js").LoginRequest} LoginRequest */
/** @typedef {import("./wire.js").Me} Me */
/** @typedef {import("./wire.js").ModelInfo} ModelInfo */
/** @typedef {import("./wire.js").PasswordChange} PasswordChange */
/** @typedef {import("./wire.js").Personalization} Personalization */
/** @typedef {import("./wire.js").PersonalizationChange} PersonalizationChange */
/** @typedef {import("./wire.js").PersonalizationExport} PersonalizationExport */
/** @typedef {import("./wire.js").RecordingControl} RecordingControl */
/** @typedef {import("./wire.js").RegisteredEstimator} RegisteredEstimator */
/** @typedef {import("./wire.js").RerunChoices} RerunChoices */
/** @typedef {import("./wire.js").RerunRequest} RerunRequest */
/** @typedef {import("./wire.js").ReviewAnnotation} ReviewAnnotation */
/** @typedef {import("./wire.js").ReviewAnnotationCreate} ReviewAnnotationCreate */
/** @typedef {import("./wire.js").Session} Session */
/** @typedef {import("./wire.js").SessionCreate} SessionCreate */
/** @typedef {import("./wire.js").SessionSettings} SessionSettings */
/** @typedef {import("./wire.js").SessionSummary} SessionSummary */
/** @typedef {import("./wire.js").SettingsChange} SettingsChange */
/** @typedef {import("./wire.js").SettingsUndo} SettingsUndo */
/** @typedef {import("./wire.js").Subject} Subject */
/** @typedef {import("./wire.js").SubjectCreate} SubjectCreate */
/** @typedef {import("./wire.js").SubjectLimits} SubjectLimits */
/** @typedef {import("./wire.js").SummaryProgress} SummaryProgress */
/** @typedef {import("./wire.js").TorqueCheck} TorqueCheck */
/** @typedef {import("./wire.js").Trial} Trial */
/** @typedef {import("./wire.js").Upload} Upload */
/** @typedef {import("./wire.js").UploadCreate} UploadCreate */
/** @typedef {import("./wire.js").User} User */
/** @typedef {import("./wire.js").UserChange} UserChange */
/** @typedef {import("./wire.js").UserCreate} UserCreate */
/** @typedef {import("./wire.js").ViewerFocus} ViewerFocus */
/** @typedef {import("./wire.js").ViewerShow} ViewerShow */

/** A path parameter as it goes in the address. @param {string | number} v */
const _p = (v) => encodeURIComponent(String(v));

/**
 * The address of `GET /api/health`.
 * @returns {string}
 */
export function healthUrl() {
  return "/api/health";
}

/**
 * `GET /api/health`: ``status`` (always ``"ok"`` when it answers), ``version`` and ``instance`` (see
 * :data:`INSTANCE`).
 * @returns {Promise<Object<string, string>>}
 */
export function health() {
  return api("GET", healthUrl());
}

/**
 * The address of `GET /api/schema`.
 * @returns {string}
 */
export function wireSchemaUrl() {
  return "/api/schema";
}

/**
 * `GET /api/schema`: JSON schema of every message that crosses a socket or a file.
 * @returns {Promise<Object<string, *>>}
 */
export function wireSchema() {
  return api("GET", wireSchemaUrl());
}

/**
 * The address of `GET /api/cluster/route`.
 * @returns {string}
 */
export function routeUrl() {
  return "/api/cluster/route";
}

/**
 * `GET /api/cluster/route`: Which node answers ``X-Forwarded-Method X-Forwarded-Uri``: ``X-Gaitscope-
 * Node``, ``X-Gaitscope-Upstream``.
 * @returns {Promise<null>}
 */
export function route() {
  return api("GET", routeUrl());
}

/**
 * The address of `GET /api/cluster/nodes`.
 * @returns {string}
 */
export function listNodesUrl() {
  return "/api/cluster/nodes";
}

/**
 * `GET /api/cluster/nodes`: Every node of the cluster, live or gone, with the sessions each runs.
 * @returns {Promise<Array<ClusterNode>>}
 */
export function listNodes() {
  return api("GET", listNodesUrl());
}

/**
 * The address of `POST /api/auth/login`.
 * @returns {string}
 */
export function loginUrl() {
  return "/api/auth/login";
}

/**
 * `POST /api/auth/login`: Check the name and password; 401 with one answer for an unknown name and a wrong
 * password (with the tries left as they run low, the wait once one starts), another for an attempt the
 * throttle holds back; every failure audited and counted by the throttle. A disabled account's right
 * password is told so.
 * @param {LoginRequest} body
 * @returns {Promise<Me>}
 */
export function login(body) {
  return api("POST", loginUrl(), body);
}

/**
 * The address of `POST /api/auth/logout`.
 * @returns {string}
 */
export function logoutUrl() {
  return "/api/auth/logout";
}

/**
 * `POST /api/auth/logout`
 * @returns {Promise<null>}
 */
export function logout() {
  return api("POST", logoutUrl());
}

/**
 * The address of `GET /api/auth/me`.
 * @returns {string}
 */
export function meUrl() {
  return "/api/auth/me";
}

/**
 * `GET /api/auth/me`: Who the server takes the caller to be: 401 when accounts are on and nobody is logged
 * in.
 * @returns {Promise<Me>}
 */
export function me() {
  return api("GET", meUrl());
}

/**
 * The address of `POST /api/auth/password`.
 * @returns {string}
 */
export function changePasswordUrl() {
  return "/api/auth/password";
}

/**
 * `POST /api/auth/password`: Change one's own password (the current one checked; a wrong one counts as a
 * failed login from this address); every login of the account ends, this one too, and their open streams
 * close. A sync route: the hashes run in a worker thread, outside any transaction.
 * @param {PasswordChange} body
 * @returns {Promise<null>}
 */
export function changePassword(body) {
  return api("POST", changePasswordUrl(), body);
}

/**
 * The address of `GET /api/users`.
 * @returns {string}
 */
export function listUsersUrl() {
  return "/api/users";
}

/**
 * `GET /api/users`
 * @returns {Promise<Array<User>>}
 */
export function listUsers() {
  return api("GET", listUsersUrl());
}

/**
 * The address of `POST /api/users`.
 * @returns {string}
 */
export function addUserUrl() {
  return "/api/users";
}

/**
 * `POST /api/users`: A new account (409 if the name is taken).
 * @param {UserCreate} body
 * @returns {Promise<User>}
 */
export function addUser(body) {
  return api("POST", addUserUrl(), body);
}

/**
 * The address of `PATCH /api/users/{name}`.
 * @param {string} name
 * @returns {string}
 */
export function changeUserUrl(name) {
  return `/api/users/${_p(name)}`;
}

/**
 * `PATCH /api/users/{name}`: Change a role, disable or enable, unlock (forget its failed logins and the
 * throttle's counts at its name), or reset the password; the account's logins end, and their open sockets
 * close, when its role changes, it is disabled or its password reset. 409 for the last admin.
 * @param {string} name
 * @param {UserChange} body
 * @returns {Promise<User>}
 */
export function changeUser(name, body) {
  return api("PATCH", changeUserUrl(name), body);
}

/**
 * The address of `GET /api/sessions/{session_id}/device-tokens`.
 * @param {number} sessionId
 * @returns {string}
 */
export function listTokensUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/device-tokens`;
}

/**
 * `GET /api/sessions/{session_id}/device-tokens`
 * @param {number} sessionId
 * @returns {Promise<Array<DeviceToken>>}
 */
export function listTokens(sessionId) {
  return api("GET", listTokensUrl(sessionId));
}

/**
 * The address of `POST /api/sessions/{session_id}/device-tokens`.
 * @param {number} sessionId
 * @returns {string}
 */
export function issueTokenUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/device-tokens`;
}

/**
 * `POST /api/sessions/{session_id}/device-tokens`
 * @param {number} sessionId
 * @returns {Promise<DeviceToken>}
 */
export function issueToken(sessionId) {
  return api("POST", issueTokenUrl(sessionId));
}

/**
 * The address of `DELETE /api/sessions/{session_id}/device-tokens/{token_id}`.
 * @param {number} sessionId
 * @param {number} tokenId
 * @returns {string}
 */
export function revokeTokenUrl(sessionId, tokenId) {
  return `/api/sessions/${_p(sessionId)}/device-tokens/${_p(tokenId)}`;
}

/**
 * `DELETE /api/sessions/{session_id}/device-tokens/{token_id}`
 * @param {number} sessionId
 * @param {number} tokenId
 * @returns {Promise<DeviceToken>}
 */
export function revokeToken(sessionId, tokenId) {
  return api("DELETE", revokeTokenUrl(sessionId, tokenId));
}

/**
 * The address of `GET /api/subjects`.
 * @returns {string}
 */
export function listSubjectsUrl() {
  return "/api/subjects";
}

/**
 * `GET /api/subjects`
 * @returns {Promise<Array<Subject>>}
 */
export function listSubjects() {
  return api("GET", listSubjectsUrl());
}

/**
 * The address of `POST /api/subjects`.
 * @returns {string}
 */
export function createSubjectUrl() {
  return "/api/subjects";
}

/**
 * `POST /api/subjects`
 * @param {SubjectCreate} body
 * @returns {Promise<Subject>}
 */
export function createSubject(body) {
  return api("POST", createSubjectUrl(), body);
}

/**
 * The address of `GET /api/subjects/{subject_id}`.
 * @param {number} subjectId
 * @returns {string}
 */
export function getSubjectUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}`;
}

/**
 * `GET /api/subjects/{subject_id}`
 * @param {number} subjectId
 * @returns {Promise<Subject>}
 */
export function getSubject(subjectId) {
  return api("GET", getSubjectUrl(subjectId));
}

/**
 * The address of `GET /api/subjects/{subject_id}/assistance-limits`.
 * @param {number} subjectId
 * @returns {string}
 */
export function assistanceLimitsUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/assistance-limits`;
}

/**
 * `GET /api/subjects/{subject_id}/assistance-limits`: The most assistance an experimenter may set for the
 * subject; null: none set (an experimenter may not change assistance at all, nor start a device session).
 * @param {number} subjectId
 * @returns {Promise<SubjectLimits | null>}
 */
export function assistanceLimits(subjectId) {
  return api("GET", assistanceLimitsUrl(subjectId));
}

/**
 * The address of `PUT /api/subjects/{subject_id}/assistance-limits`.
 * @param {number} subjectId
 * @returns {string}
 */
export function setAssistanceLimitsUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/assistance-limits`;
}

/**
 * `PUT /api/subjects/{subject_id}/assistance-limits`: Set the experimenters' limits for the subject
 * (clinicians and admins).
 * @param {number} subjectId
 * @param {AssistanceLimits} body
 * @returns {Promise<SubjectLimits>}
 */
export function setAssistanceLimits(subjectId, body) {
  return api("PUT", setAssistanceLimitsUrl(subjectId), body);
}

/**
 * The address of `GET /api/subjects/{subject_id}/intent-model`.
 * @param {number} subjectId
 * @returns {string}
 */
export function getIntentModelUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/intent-model`;
}

/**
 * `GET /api/subjects/{subject_id}/intent-model`: The speed-change intent model the subject's next session
 * runs (the default when none was set).
 * @param {number} subjectId
 * @returns {Promise<object>}
 */
export function getIntentModel(subjectId) {
  return api("GET", getIntentModelUrl(subjectId));
}

/**
 * The address of `PUT /api/subjects/{subject_id}/intent-model`.
 * @param {number} subjectId
 * @returns {string}
 */
export function setIntentModelUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/intent-model`;
}

/**
 * `PUT /api/subjects/{subject_id}/intent-model`: Set the subject's intent model: fitted on a trial of
 * theirs (in a worker thread; 422 with the reason when the trial cannot serve), or the variant's default.
 * It runs from the subject's next session on (a running session keeps the model it started with, so nothing
 * that drives a torque now changes).
 * @param {number} subjectId
 * @param {object} body
 * @returns {Promise<object>}
 */
export function setIntentModel(subjectId, body) {
  return api("PUT", setIntentModelUrl(subjectId), body);
}

/**
 * The address of `DELETE /api/subjects/{subject_id}/intent-model`.
 * @param {number} subjectId
 * @returns {string}
 */
export function resetIntentModelUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/intent-model`;
}

/**
 * `DELETE /api/subjects/{subject_id}/intent-model`: Back to the default model (the cohort's kappa) from the
 * subject's next session on; 404 when it is already.
 * @param {number} subjectId
 * @returns {Promise<object>}
 */
export function resetIntentModel(subjectId) {
  return api("DELETE", resetIntentModelUrl(subjectId));
}

/**
 * The address of `GET /api/subjects/{subject_id}/fingerprints`.
 * @param {number} subjectId
 * @param {{model?: string}} [params]
 * @returns {string}
 */
export function listFingerprintsUrl(subjectId, params = {}) {
  return `/api/subjects/${_p(subjectId)}/fingerprints${query(params)}`;
}

/**
 * `GET /api/subjects/{subject_id}/fingerprints`: The subject's personalizations of ``model``, newest first,
 * the active one, and the training subjects' fingerprints (where this subject sits among them).
 * @param {number} subjectId
 * @param {{model?: string}} [params]
 * @returns {Promise<Fingerprints>}
 */
export function listFingerprints(subjectId, params = {}) {
  return api("GET", listFingerprintsUrl(subjectId, params));
}

/**
 * The address of `POST /api/subjects/{subject_id}/fingerprints`.
 * @param {number} subjectId
 * @returns {string}
 */
export function calibrateFingerprintUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/fingerprints`;
}

/**
 * `POST /api/subjects/{subject_id}/fingerprints`: Fit a fingerprint from one of the subject's trials, in a
 * worker thread (live streams go on); stored as a ``candidate``: nothing runs it until it is promoted. 422
 * with the reason when the walk cannot serve.
 * @param {number} subjectId
 * @param {CalibrationRequest} body
 * @returns {Promise<Personalization>}
 */
export function calibrateFingerprint(subjectId, body) {
  return api("POST", calibrateFingerprintUrl(subjectId), body);
}

/**
 * The address of `POST /api/subjects/{subject_id}/fingerprints/{personalization_id}/promote`.
 * @param {number} subjectId
 * @param {number} personalizationId
 * @returns {string}
 */
export function promoteFingerprintUrl(subjectId, personalizationId) {
  return `/api/subjects/${_p(subjectId)}/fingerprints/${_p(personalizationId)}/promote`;
}

/**
 * `POST /api/subjects/{subject_id}/fingerprints/{personalization_id}/promote`: Make it the subject's active
 * personalization; running sessions take it at their next heel strike.
 * @param {number} subjectId
 * @param {number} personalizationId
 * @param {PersonalizationChange} body
 * @returns {Promise<Personalization>}
 */
export function promoteFingerprint(subjectId, personalizationId, body) {
  return api("POST", promoteFingerprintUrl(subjectId, personalizationId), body);
}

/**
 * The address of `POST /api/subjects/{subject_id}/fingerprints/rollback`.
 * @param {number} subjectId
 * @param {{model?: string}} [params]
 * @returns {string}
 */
export function rollbackFingerprintUrl(subjectId, params = {}) {
  return `/api/subjects/${_p(subjectId)}/fingerprints/rollback${query(params)}`;
}

/**
 * `POST /api/subjects/{subject_id}/fingerprints/rollback`: Retire the active personalization; the one it
 * replaced is active again (none: the average model).
 * @param {number} subjectId
 * @param {PersonalizationChange} body
 * @param {{model?: string}} [params]
 * @returns {Promise<Fingerprints>}
 */
export function rollbackFingerprint(subjectId, body, params = {}) {
  return api("POST", rollbackFingerprintUrl(subjectId, params), body);
}

/**
 * The address of `GET /api/subjects/{subject_id}/fingerprints/{personalization_id}/export`.
 * @param {number} subjectId
 * @param {number} personalizationId
 * @returns {string}
 */
export function exportFingerprintUrl(subjectId, personalizationId) {
  return `/api/subjects/${_p(subjectId)}/fingerprints/${_p(personalizationId)}/export`;
}

/**
 * `GET /api/subjects/{subject_id}/fingerprints/{personalization_id}/export`: The personalization as a file
 * another gaitscope can import (with the same model).
 * @param {number} subjectId
 * @param {number} personalizationId
 * @returns {Promise<*>}
 */
export function exportFingerprint(subjectId, personalizationId) {
  return api("GET", exportFingerprintUrl(subjectId, personalizationId));
}

/**
 * The address of `POST /api/subjects/{subject_id}/fingerprints/import`.
 * @param {number} subjectId
 * @returns {string}
 */
export function importFingerprintUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/fingerprints/import`;
}

/**
 * `POST /api/subjects/{subject_id}/fingerprints/import`: A personalization exported elsewhere, as a new
 * ``candidate``; refused (422) when its model's map is not this machine's (another training-data hash, or
 * another number of components).
 * @param {number} subjectId
 * @param {PersonalizationExport} body
 * @returns {Promise<Personalization>}
 */
export function importFingerprint(subjectId, body) {
  return api("POST", importFingerprintUrl(subjectId), body);
}

/**
 * The address of `GET /api/sessions`.
 * @param {{subject_id?: number | null}} [params]
 * @returns {string}
 */
export function listSessionsUrl(params = {}) {
  return `/api/sessions${query(params)}`;
}

/**
 * `GET /api/sessions`
 * @param {{subject_id?: number | null}} [params]
 * @returns {Promise<Array<Session>>}
 */
export function listSessions(params = {}) {
  return api("GET", listSessionsUrl(params));
}

/**
 * The address of `POST /api/sessions`.
 * @returns {string}
 */
export function createSessionUrl() {
  return "/api/sessions";
}

/**
 * `POST /api/sessions`
 * @param {SessionCreate} body
 * @returns {Promise<Session>}
 */
export function createSession(body) {
  return api("POST", createSessionUrl(), body);
}

/**
 * The address of `GET /api/sessions/{session_id}`.
 * @param {number} sessionId
 * @returns {string}
 */
export function getSessionUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}`;
}

/**
 * `GET /api/sessions/{session_id}`
 * @param {number} sessionId
 * @returns {Promise<Session>}
 */
export function getSession(sessionId) {
  return api("GET", getSessionUrl(sessionId));
}

/**
 * The address of `POST /api/sessions/{session_id}/start`.
 * @param {number} sessionId
 * @returns {string}
 */
export function startSessionUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/start`;
}

/**
 * `POST /api/sessions/{session_id}/start`
 * @param {number} sessionId
 * @returns {Promise<Session>}
 */
export function startSession(sessionId) {
  return api("POST", startSessionUrl(sessionId));
}

/**
 * The address of `POST /api/sessions/{session_id}/stop`.
 * @param {number} sessionId
 * @returns {string}
 */
export function stopSessionUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/stop`;
}

/**
 * `POST /api/sessions/{session_id}/stop`: Stop a session. Stopping takes the assistance off the person, so
 * it is never refused for want of an audit entry: when a full disk refuses the entry, the session stops all
 * the same (the refusal is logged, and the session's own stop event, kept until the disk has room, names
 * the stop) and the answer is 507 saying so.
 * @param {number} sessionId
 * @returns {Promise<Session>}
 */
export function stopSession(sessionId) {
  return api("POST", stopSessionUrl(sessionId));
}

/**
 * The address of `PATCH /api/sessions/{session_id}/settings`.
 * @param {number} sessionId
 * @returns {string}
 */
export function changeSettingsUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/settings`;
}

/**
 * `PATCH /api/sessions/{session_id}/settings`: Change a running session's settings. A change that can raise
 * the torque on the person (a raise of the torque gain, the maximum torque or the intent boost, a switch of
 * the primary) needs ``confirm``: without it the answer is 409 with a ``TorqueRaiseRefused`` naming the
 * peak torque before and after, to show and resend confirmed; at most one such change every
 * ``TORQUE_RAISE_INTERVAL_S`` (``gaitscope.sessions.live.torque_rule``).
 * @param {number} sessionId
 * @param {SettingsChange} body
 * @returns {Promise<Session>}
 */
export function changeSettings(sessionId, body) {
  return api("PATCH", changeSettingsUrl(sessionId), body);
}

/**
 * The address of `POST /api/sessions/{session_id}/settings/check`.
 * @param {number} sessionId
 * @returns {string}
 */
export function checkSettingsUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/settings/check`;
}

/**
 * `POST /api/sessions/{session_id}/settings/check`: What a settings change would do to the torque of a
 * running session, changing nothing: whether it needs ``confirm`` (``fields``), the peak torque before and
 * after, how long until it may be made. The dashboard asks its user with it before it sends the change.
 * @param {number} sessionId
 * @param {SettingsChange} body
 * @returns {Promise<TorqueCheck>}
 */
export function checkSettings(sessionId, body) {
  return api("POST", checkSettingsUrl(sessionId), body);
}

/**
 * The address of `GET /api/sessions/{session_id}/events`.
 * @param {number} sessionId
 * @returns {string}
 */
export function sessionEventsUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/events`;
}

/**
 * `GET /api/sessions/{session_id}/events`
 * @param {number} sessionId
 * @returns {Promise<Array<Event>>}
 */
export function sessionEvents(sessionId) {
  return api("GET", sessionEventsUrl(sessionId));
}

/**
 * The address of `POST /api/sessions/{session_id}/annotations`.
 * @param {number} sessionId
 * @returns {string}
 */
export function annotateUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/annotations`;
}

/**
 * `POST /api/sessions/{session_id}/annotations`
 * @param {number} sessionId
 * @param {AnnotationCreate} body
 * @returns {Promise<Event>}
 */
export function annotate(sessionId, body) {
  return api("POST", annotateUrl(sessionId), body);
}

/**
 * The address of `POST /api/sessions/{session_id}/recording`.
 * @param {number} sessionId
 * @returns {string}
 */
export function recordingUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/recording`;
}

/**
 * `POST /api/sessions/{session_id}/recording`
 * @param {number} sessionId
 * @param {RecordingControl} body
 * @returns {Promise<Trial>}
 */
export function recording(sessionId, body) {
  return api("POST", recordingUrl(sessionId), body);
}

/**
 * The address of `GET /api/estimators`.
 * @returns {string}
 */
export function listEstimatorsUrl() {
  return "/api/estimators";
}

/**
 * `GET /api/estimators`: Every registered estimator, in the order a stack runs them, with its cost per
 * sample here (null when the warm-up did not time it). Which of them a source can feed stays the session's
 * start to judge (409 naming the missing channels).
 * @returns {Promise<Array<RegisteredEstimator>>}
 */
export function listEstimators() {
  return api("GET", listEstimatorsUrl());
}

/**
 * The address of `GET /api/sessions/{session_id}/imu-calibration`.
 * @param {number} sessionId
 * @returns {string}
 */
export function imuCalibrationUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/imu-calibration`;
}

/**
 * `GET /api/sessions/{session_id}/imu-calibration`: The running session's calibration: idle, collecting
 * (progress), done or refused (each sensor's outcome), and what its front ends run; a session not running:
 * idle, with its latest stored one.
 * @param {number} sessionId
 * @returns {Promise<ImuCalibrationStatus>}
 */
export function imuCalibration(sessionId) {
  return api("GET", imuCalibrationUrl(sessionId));
}

/**
 * The address of `POST /api/sessions/{session_id}/imu-calibration`.
 * @param {number} sessionId
 * @returns {string}
 */
export function startImuCalibrationUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/imu-calibration`;
}

/**
 * `POST /api/sessions/{session_id}/imu-calibration`: Collect ``duration_s`` of the running session's raw
 * IMU samples, then calibrate and, when every sensor was still, apply; follow it with the GET. 409: not
 * running, no IMU front end, one collecting.
 * @param {number} sessionId
 * @param {ImuCalibrationRequest | null} [body]
 * @returns {Promise<ImuCalibrationStatus>}
 */
export function startImuCalibration(sessionId, body) {
  return api("POST", startImuCalibrationUrl(sessionId), body);
}

/**
 * The address of `GET /api/subjects/{subject_id}/imu-calibrations`.
 * @param {number} subjectId
 * @returns {string}
 */
export function subjectImuCalibrationsUrl(subjectId) {
  return `/api/subjects/${_p(subjectId)}/imu-calibrations`;
}

/**
 * `GET /api/subjects/{subject_id}/imu-calibrations`: The subject's accepted calibrations, newest first: the
 * first is their current one (their next session's front ends start with it).
 * @param {number} subjectId
 * @returns {Promise<Array<ImuCalibration>>}
 */
export function subjectImuCalibrations(subjectId) {
  return api("GET", subjectImuCalibrationsUrl(subjectId));
}

/**
 * The address of `GET /api/sessions/{session_id}/gp-learning`.
 * @param {number} sessionId
 * @param {{version?: number | null}} [params]
 * @returns {string}
 */
export function gpLearningUrl(sessionId, params = {}) {
  return `/api/sessions/${_p(sessionId)}/gp-learning${query(params)}`;
}

/**
 * `GET /api/sessions/{session_id}/gp-learning`: The GP-EKF's learning: the version in use, the one waiting
 * for the next heel strike, a fit under way, the kept versions (training window, held-out RMSE, install
 * times), frozen or not, and the learned mean of each joint angle with its +-2 sd band over stance phase
 * for the version in use (and ``version``'s, a kept one: 422 otherwise). 409: not running, or no GP-EKF in
 * its stack.
 * @param {number} sessionId
 * @param {{version?: number | null}} [params]
 * @returns {Promise<GPLearningState>}
 */
export function gpLearning(sessionId, params = {}) {
  return api("GET", gpLearningUrl(sessionId, params));
}

/**
 * The address of `POST /api/sessions/{session_id}/gp-learning`.
 * @param {number} sessionId
 * @returns {string}
 */
export function controlGpLearningUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/gp-learning`;
}

/**
 * `POST /api/sessions/{session_id}/gp-learning`: Freeze or unfreeze the learning, or roll back to a kept
 * version (installed at the next heel strike); logged as an event with the actor and recorded. 409: not
 * running, no GP-EKF, or it failed; 422: a bad body, or a version that is not kept.
 * @param {number} sessionId
 * @param {GPLearningControl} body
 * @returns {Promise<GPLearningState>}
 */
export function controlGpLearning(sessionId, body) {
  return api("POST", controlGpLearningUrl(sessionId), body);
}

/**
 * The address of `GET /api/trials`.
 * @param {{session_id?: number | null}} [params]
 * @returns {string}
 */
export function listTrialsUrl(params = {}) {
  return `/api/trials${query(params)}`;
}

/**
 * `GET /api/trials`
 * @param {{session_id?: number | null}} [params]
 * @returns {Promise<Array<Trial>>}
 */
export function listTrials(params = {}) {
  return api("GET", listTrialsUrl(params));
}

/**
 * The address of `GET /api/trials/{trial_id}`.
 * @param {number} trialId
 * @returns {string}
 */
export function getTrialUrl(trialId) {
  return `/api/trials/${_p(trialId)}`;
}

/**
 * `GET /api/trials/{trial_id}`
 * @param {number} trialId
 * @returns {Promise<Trial>}
 */
export function getTrial(trialId) {
  return api("GET", getTrialUrl(trialId));
}

/**
 * The address of `GET /api/trials/{trial_id}/events`.
 * @param {number} trialId
 * @returns {string}
 */
export function trialEventsUrl(trialId) {
  return `/api/trials/${_p(trialId)}/events`;
}

/**
 * `GET /api/trials/{trial_id}/events`
 * @param {number} trialId
 * @returns {Promise<Array<Event>>}
 */
export function trialEvents(trialId) {
  return api("GET", trialEventsUrl(trialId));
}

/**
 * The address of `GET /api/trials/{trial_id}/series`.
 * @param {number} trialId
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {string}
 */
export function trialSeriesUrl(trialId, params = {}) {
  return `/api/trials/${_p(trialId)}/series${query(params)}`;
}

/**
 * `GET /api/trials/{trial_id}/series`
 * @param {number} trialId
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {Promise<Object<string, Array<*>>>}
 */
export function trialSeries(trialId, params = {}) {
  return api("GET", trialSeriesUrl(trialId, params));
}

/**
 * The address of `GET /api/trials/{trial_id}/intent`.
 * @param {number} trialId
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {string}
 */
export function trialIntentUrl(trialId, params = {}) {
  return `/api/trials/${_p(trialId)}/intent${query(params)}`;
}

/**
 * `GET /api/trials/{trial_id}/intent`: The speed-change intent over the trial (desired and actual speed,
 * decimated as ``/series``) as its ``intent`` estimator recorded it, or the channels that estimator needs
 * and the trial lacks.
 * @param {number} trialId
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {Promise<IntentSeries>}
 */
export function trialIntent(trialId, params = {}) {
  return api("GET", trialIntentUrl(trialId, params));
}

/**
 * The address of `GET /api/trials/{trial_id}/download`.
 * @param {number} trialId
 * @returns {string}
 */
export function downloadUrl(trialId) {
  return `/api/trials/${_p(trialId)}/download`;
}

/**
 * `GET /api/trials/{trial_id}/download`
 * @param {number} trialId
 * @returns {Promise<*>}
 */
export function download(trialId) {
  return api("GET", downloadUrl(trialId));
}

/**
 * The address of `GET /api/trials/{trial_id}/settings`.
 * @param {number} trialId
 * @returns {string}
 */
export function trialSettingsUrl(trialId) {
  return `/api/trials/${_p(trialId)}/settings`;
}

/**
 * `GET /api/trials/{trial_id}/settings`: The settings in force at the trial's first frame, as recorded (its
 * changes are on ``/events``).
 * @param {number} trialId
 * @returns {Promise<SessionSettings>}
 */
export function trialSettings(trialId) {
  return api("GET", trialSettingsUrl(trialId));
}

/**
 * The address of `GET /api/trials/{trial_id}/estimators`.
 * @param {number} trialId
 * @returns {string}
 */
export function trialEstimatorsUrl(trialId) {
  return `/api/trials/${_p(trialId)}/estimators`;
}

/**
 * `GET /api/trials/{trial_id}/estimators`: Which estimators a re-run of the trial can run: its recorded
 * stack and those its channels feed.
 * @param {number} trialId
 * @returns {Promise<RerunChoices>}
 */
export function trialEstimators(trialId) {
  return api("GET", trialEstimatorsUrl(trialId));
}

/**
 * The address of `POST /api/trials/{trial_id}/rerun`.
 * @param {number} trialId
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {string}
 */
export function rerunUrl(trialId, params = {}) {
  return `/api/trials/${_p(trialId)}/rerun${query(params)}`;
}

/**
 * `POST /api/trials/{trial_id}/rerun`: The trial's raw frames through the estimators again (series like
 * ``/series``, plus each estimator's outputs as ``<name>.<output>`` columns): as recorded by default, or
 * with the body's settings over the whole trial (what if), and the recorded stack or the body's
 * ``estimators``; see ``RerunRequest``.
 * @param {number} trialId
 * @param {RerunRequest | null} [body]
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {Promise<Object<string, Array<*>>>}
 */
export function rerun(trialId, body, params = {}) {
  return api("POST", rerunUrl(trialId, params), body);
}

/**
 * The address of `POST /api/trials/{trial_id}/compare`.
 * @param {number} trialId
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {string}
 */
export function compareUrl(trialId, params = {}) {
  return `/api/trials/${_p(trialId)}/compare${query(params)}`;
}

/**
 * `POST /api/trials/{trial_id}/compare`: Two or more named re-runs of the trial side by side (A/B): each
 * one's torque and phase, its difference from the first, its mean stride and its figures (peak torque, mean
 * phase rate, stride length; errors against the ground truth when the trial has one: a simulated session's
 * walk).
 * @param {number} trialId
 * @param {CompareRequest} body
 * @param {{t0?: number | null, t1?: number | null, max_points?: number}} [params]
 * @returns {Promise<Comparison>}
 */
export function compare(trialId, body, params = {}) {
  return api("POST", compareUrl(trialId, params), body);
}

/**
 * The address of `GET /api/trials/{trial_id}/annotations`.
 * @param {number} trialId
 * @returns {string}
 */
export function listAnnotationsUrl(trialId) {
  return `/api/trials/${_p(trialId)}/annotations`;
}

/**
 * `GET /api/trials/{trial_id}/annotations`: The trial's notes by time: added in review, and taken live
 * while it recorded (``source`` ``live``).
 * @param {number} trialId
 * @returns {Promise<Array<ReviewAnnotation>>}
 */
export function listAnnotations(trialId) {
  return api("GET", listAnnotationsUrl(trialId));
}

/**
 * The address of `POST /api/trials/{trial_id}/annotations`.
 * @param {number} trialId
 * @returns {string}
 */
export function addAnnotationUrl(trialId) {
  return `/api/trials/${_p(trialId)}/annotations`;
}

/**
 * `POST /api/trials/{trial_id}/annotations`: A note at a time (``t``) or over a span (``t`` to ``t_end``)
 * of the trial, saved with it; 422 when it lies outside the recording.
 * @param {number} trialId
 * @param {ReviewAnnotationCreate} body
 * @returns {Promise<ReviewAnnotation>}
 */
export function addAnnotation(trialId, body) {
  return api("POST", addAnnotationUrl(trialId), body);
}

/**
 * The address of `DELETE /api/trials/{trial_id}/annotations/{annotation_id}`.
 * @param {number} trialId
 * @param {number} annotationId
 * @returns {string}
 */
export function deleteAnnotationUrl(trialId, annotationId) {
  return `/api/trials/${_p(trialId)}/annotations/${_p(annotationId)}`;
}

/**
 * `DELETE /api/trials/{trial_id}/annotations/{annotation_id}`: Delete a note; only whoever wrote it may
 * (403 for anyone else).
 * @param {number} trialId
 * @param {number} annotationId
 * @returns {Promise<null>}
 */
export function deleteAnnotation(trialId, annotationId) {
  return api("DELETE", deleteAnnotationUrl(trialId, annotationId));
}

/**
 * The address of `GET /api/models`.
 * @returns {string}
 */
export function listModelsUrl() {
  return "/api/models";
}

/**
 * `GET /api/models`
 * @returns {Promise<Array<ModelInfo>>}
 */
export function listModels() {
  return api("GET", listModelsUrl());
}

/**
 * The address of `GET /api/sessions/{session_id}/summary`.
 * @param {number} sessionId
 * @returns {string}
 */
export function summaryUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/summary`;
}

/**
 * `GET /api/sessions/{session_id}/summary`: Duration (recorded, and the wall time), strides, speed and
 * incline profile, settings history, per-condition stride curves, data health and events of a session (its
 * trials still recording are left out).
 * @param {number} sessionId
 * @returns {Promise<SessionSummary>}
 */
export function summary(sessionId) {
  return api("GET", summaryUrl(sessionId));
}

/**
 * The address of `GET /api/sessions/{session_id}/summary/progress`.
 * @param {number} sessionId
 * @returns {string}
 */
export function summaryProgressUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/summary/progress`;
}

/**
 * `GET /api/sessions/{session_id}/summary/progress`: How far the making of the session's summary has got
 * (for the page waiting for it), or that it is ready.
 * @param {number} sessionId
 * @returns {Promise<SummaryProgress>}
 */
export function summaryProgress(sessionId) {
  return api("GET", summaryProgressUrl(sessionId));
}

/**
 * The address of `POST /api/sessions/{session_id}/exports`.
 * @param {number} sessionId
 * @returns {string}
 */
export function startExportUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/exports`;
}

/**
 * `POST /api/sessions/{session_id}/exports`
 * @param {number} sessionId
 * @param {ExportCreate} body
 * @returns {Promise<ExportJob>}
 */
export function startExport(sessionId, body) {
  return api("POST", startExportUrl(sessionId), body);
}

/**
 * The address of `POST /api/trials/{trial_id}/exports`.
 * @param {number} trialId
 * @returns {string}
 */
export function startTrialExportUrl(trialId) {
  return `/api/trials/${_p(trialId)}/exports`;
}

/**
 * `POST /api/trials/{trial_id}/exports`: A PDF report or a CSV of the estimates of one trial (the review
 * page links them).
 * @param {number} trialId
 * @param {ExportCreate} body
 * @returns {Promise<ExportJob>}
 */
export function startTrialExport(trialId, body) {
  return api("POST", startTrialExportUrl(trialId), body);
}

/**
 * The address of `GET /api/exports/{job_id}`.
 * @param {string} jobId
 * @returns {string}
 */
export function getExportUrl(jobId) {
  return `/api/exports/${_p(jobId)}`;
}

/**
 * `GET /api/exports/{job_id}`
 * @param {string} jobId
 * @returns {Promise<ExportJob>}
 */
export function getExport(jobId) {
  return api("GET", getExportUrl(jobId));
}

/**
 * The address of `GET /api/exports/{job_id}/file`.
 * @param {string} jobId
 * @returns {string}
 */
export function exportFileUrl(jobId) {
  return `/api/exports/${_p(jobId)}/file`;
}

/**
 * `GET /api/exports/{job_id}/file`
 * @param {string} jobId
 * @returns {Promise<*>}
 */
export function exportFile(jobId) {
  return api("GET", exportFileUrl(jobId));
}

/**
 * The address of `GET /api/viewer`.
 * @returns {string}
 */
export function viewerUrl() {
  return "/api/viewer";
}

/**
 * `GET /api/viewer`
 * @returns {Promise<Object<string, string | null>>}
 */
export function viewer() {
  return api("GET", viewerUrl());
}

/**
 * The address of `POST /api/viewer/focus`.
 * @returns {string}
 */
export function viewerFocusUrl() {
  return "/api/viewer/focus";
}

/**
 * `POST /api/viewer/focus`
 * @param {ViewerFocus} body
 * @returns {Promise<Object<string, number | null>>}
 */
export function viewerFocus(body) {
  return api("POST", viewerFocusUrl(), body);
}

/**
 * The address of `POST /api/viewer/show`.
 * @returns {string}
 */
export function viewerShowUrl() {
  return "/api/viewer/show";
}

/**
 * `POST /api/viewer/show`: Pose the leg view at time ``t`` of a trial (the review page's cursor).
 * @param {ViewerShow} body
 * @returns {Promise<Object<string, number>>}
 */
export function viewerShow(body) {
  return api("POST", viewerShowUrl(), body);
}

/**
 * The address of `POST /api/uploads`.
 * @returns {string}
 */
export function createUploadUrl() {
  return "/api/uploads";
}

/**
 * `POST /api/uploads`
 * @param {UploadCreate} body
 * @returns {Promise<Upload>}
 */
export function createUpload(body) {
  return api("POST", createUploadUrl(), body);
}

/**
 * The address of `PUT /api/uploads/{upload_id}`.
 * @param {string} uploadId
 * @param {{offset: number}} params
 * @returns {string}
 */
export function uploadChunkUrl(uploadId, params) {
  return `/api/uploads/${_p(uploadId)}${query(params)}`;
}

/**
 * `PUT /api/uploads/{upload_id}`
 * @param {string} uploadId
 * @param {Blob} body
 * @param {{offset: number}} params
 * @returns {Promise<Upload>}
 */
export function uploadChunk(uploadId, body, params) {
  return apiBytes("PUT", uploadChunkUrl(uploadId, params), body);
}

/**
 * The address of `DELETE /api/uploads/{upload_id}`.
 * @param {string} uploadId
 * @returns {string}
 */
export function cancelUploadUrl(uploadId) {
  return `/api/uploads/${_p(uploadId)}`;
}

/**
 * `DELETE /api/uploads/{upload_id}`
 * @param {string} uploadId
 * @returns {Promise<null>}
 */
export function cancelUpload(uploadId) {
  return api("DELETE", cancelUploadUrl(uploadId));
}

/**
 * The address of `POST /api/uploads/{upload_id}/preview`.
 * @param {string} uploadId
 * @returns {string}
 */
export function previewUploadUrl(uploadId) {
  return `/api/uploads/${_p(uploadId)}/preview`;
}

/**
 * `POST /api/uploads/{upload_id}/preview`: What an import of the (complete) upload would read, from its
 * first seconds: the channels, a small plot of each, what they feed, what looks wrong, and the channel
 * mapping in use for a file that needs one (given, saved for the file's rig, or suggested). Nothing is
 * stored; the upload stays open.
 * @param {string} uploadId
 * @param {object | null} [body]
 * @returns {Promise<object>}
 */
export function previewUpload(uploadId, body) {
  return api("POST", previewUploadUrl(uploadId), body);
}

/**
 * The address of `POST /api/uploads/{upload_id}/finish`.
 * @param {string} uploadId
 * @param {{recover?: boolean, keep_copy?: boolean}} [params]
 * @returns {string}
 */
export function finishUploadUrl(uploadId, params = {}) {
  return `/api/uploads/${_p(uploadId)}/finish${query(params)}`;
}

/**
 * `POST /api/uploads/{upload_id}/finish`: Import the upload; ``recover=true`` first recovers an MCAP
 * recording that was never finished; ``keep_copy=true`` stores a file uploaded before again (else 409,
 * naming its trial). ``options``: the channel mapping of another tool's MCAP recording or of a C3D file
 * (kept for the file's rig, so its next file maps itself); without it, the mapping saved for the rig, else
 * the suggested one.
 * @param {string} uploadId
 * @param {object | null} [body]
 * @param {{recover?: boolean, keep_copy?: boolean}} [params]
 * @returns {Promise<object>}
 */
export function finishUpload(uploadId, body, params = {}) {
  return api("POST", finishUploadUrl(uploadId, params), body);
}

/**
 * The address of `GET /api/mappings`.
 * @returns {string}
 */
export function listMappingsUrl() {
  return "/api/mappings";
}

/**
 * `GET /api/mappings`: The channel mappings saved per rig, newest first.
 * @returns {Promise<Array<object>>}
 */
export function listMappings() {
  return api("GET", listMappingsUrl());
}

/**
 * The address of `DELETE /api/mappings/{rig}`.
 * @param {string} rig
 * @returns {string}
 */
export function deleteMappingUrl(rig) {
  return `/api/mappings/${_p(rig)}`;
}

/**
 * `DELETE /api/mappings/{rig}`: Forget the mapping saved for ``rig`` (its next file gets the suggested one
 * again).
 * @param {string} rig
 * @returns {Promise<null>}
 */
export function deleteMapping(rig) {
  return api("DELETE", deleteMappingUrl(rig));
}

/**
 * The address of `POST /api/sessions/{session_id}/settings/undo`.
 * @param {number} sessionId
 * @returns {string}
 */
export function undoSettingsUrl(sessionId) {
  return `/api/sessions/${_p(sessionId)}/settings/undo`;
}

/**
 * `POST /api/sessions/{session_id}/settings/undo`: Undo the session's last applied settings change (409
 * with the reason when it cannot be, now; an undo that can raise the torque on the person needs
 * ``confirm``, as a settings change does).
 * @param {number} sessionId
 * @param {SettingsUndo} body
 * @returns {Promise<Session>}
 */
export function undoSettings(sessionId, body) {
  return api("POST", undoSettingsUrl(sessionId), body);
}

/**
 * The address of `GET /api/audit`.
 * @param {{user?: string | null, action?: string | null, outcome?: "requested" | "done" | "failed" | "refused" | null, target?: string | null, since?: string | null, until?: string | null, limit?: number, offset?: number}} [params]
 * @returns {string}
 */
export function listAuditUrl(params = {}) {
  return `/api/audit${query(params)}`;
}

/**
 * `GET /api/audit`: One page of the entries matching the filters, newest first (``limit`` entries from
 * ``offset``).
 * @param {{user?: string | null, action?: string | null, outcome?: "requested" | "done" | "failed" | "refused" | null, target?: string | null, since?: string | null, until?: string | null, limit?: number, offset?: number}} [params]
 * @returns {Promise<Array<AuditEntry>>}
 */
export function listAudit(params = {}) {
  return api("GET", listAuditUrl(params));
}

/**
 * The address of `GET /api/audit.csv`.
 * @param {{user?: string | null, action?: string | null, outcome?: "requested" | "done" | "failed" | "refused" | null, target?: string | null, since?: string | null, until?: string | null, limit?: number, offset?: number}} [params]
 * @returns {string}
 */
export function exportAuditUrl(params = {}) {
  return `/api/audit.csv${query(params)}`;
}

/**
 * `GET /api/audit.csv`: Every entry matching the filters (``limit``/``offset`` ignored) as CSV, oldest
 * first, streamed.
 * @param {{user?: string | null, action?: string | null, outcome?: "requested" | "done" | "failed" | "refused" | null, target?: string | null, since?: string | null, until?: string | null, limit?: number, offset?: number}} [params]
 * @returns {Promise<*>}
 */
export function exportAudit(params = {}) {
  return api("GET", exportAuditUrl(params));
}

/**
 * The address of `GET /api/audit/verify`.
 * @returns {string}
 */
export function verifyAuditUrl() {
  return "/api/audit/verify";
}

/**
 * `GET /api/audit/verify`: Walk the whole chain (a million entries take some seconds) and say whether it is
 * intact.
 * @returns {Promise<AuditVerification>}
 */
export function verifyAudit() {
  return api("GET", verifyAuditUrl());
}
