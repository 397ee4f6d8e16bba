"""``/api/sessions/{id}/imu-calibration``: a standing calibration of a live session's IMU mountings (start it,
follow it), and ``/api/subjects/{id}/imu-calibrations``: a subject's stored ones. Thin: the collecting,
calibrating, storing and applying are the session runtime's (``gaitscope.sessions.imu_calibration``)."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException

from gaitscope.server.auth import Runner, allow
from gaitscope.server.routes.common import Ctx, Id, audited, by, not_running_here
from gaitscope.sessions import schema

router = APIRouter(prefix="/api")


@router.post("/sessions/{session_id}/imu-calibration", status_code=202)
async def start_imu_calibration(
    session_id: Id, c: Ctx, who: Runner, body: schema.ImuCalibrationRequest | None = None
) -> schema.ImuCalibrationStatus:
    """Collect ``duration_s`` of the running session's raw IMU samples, then calibrate and, when every
    sensor was still, apply; follow it with the GET. 409: not running, no IMU front end, one collecting."""
    runtime = c.manager.get(session_id)
    if runtime is None:
        c.store.get_session(session_id)
        raise HTTPException(409, not_running_here(c, session_id, "; IMUs calibrate only while it runs"))
    if not runtime.imu_calibration.segments:
        raise HTTPException(
            409,
            f"session {session_id} has no IMU to calibrate: its stack runs no IMU front end (imu_foot, imu_shank, "
            "...), as its source sends no raw IMU channels",
        )
    if runtime.imu_calibration.collector is not None:
        raise HTTPException(409, f"session {session_id} is calibrating its IMUs already; wait for it to finish")
    request = by(body or schema.ImuCalibrationRequest(), who)
    await audited(c, who, "imu_calibration.start", f"session {session_id}", after=request.model_dump(exclude={"actor"}))
    return runtime.imu_calibration.calibrate(request)


@router.get("/sessions/{session_id}/imu-calibration", dependencies=[allow("read")])
def imu_calibration(session_id: Id, c: Ctx) -> schema.ImuCalibrationStatus:
    """The running session's calibration: idle, collecting (progress), done or refused (each sensor's
    outcome), and what its front ends run; a session not running: idle, with its latest stored one."""
    runtime = c.manager.get(session_id)
    if runtime is not None:
        return runtime.imu_calibration.status()
    stored = c.store.list_imu_calibrations(session_id=session_id)
    last = stored[0] if stored else None
    return schema.ImuCalibrationStatus(
        session_id=session_id, state="idle", progress=0.0, duration_s=0.0, segments=[], result=last, applied=None
    )


@router.get("/subjects/{subject_id}/imu-calibrations", dependencies=[allow("read")])
def subject_imu_calibrations(subject_id: Id, c: Ctx) -> list[schema.ImuCalibration]:
    """The subject's accepted calibrations, newest first: the first is their current one (their next
    session's front ends start with it)."""
    return c.store.list_imu_calibrations(subject_id=subject_id)
