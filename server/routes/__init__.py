"""The HTTP and websocket routes, one module per resource; thin: validation by ``gaitscope.sessions.schema``,
logic in ``sessions``. See ``docs/api.md``.

``ROUTERS`` in the order the app includes them; ``install_error_handlers`` turns domain errors into
HTTP statuses (``common.ERROR_STATUS``).
"""

from fastapi import APIRouter

from gaitscope.server.routes import (
    audit,
    auth,
    cluster,
    devices,
    estimators,
    fingerprints,
    gp_learning,
    imu_calibration,
    meta,
    models,
    reports,
    sessions,
    streams,
    subjects,
    trials,
    uploads,
    users,
    viewer,
)
from gaitscope.server.routes.common import install_error_handlers
from gaitscope.server.routes.uploads import Uploads

ROUTERS: tuple[APIRouter, ...] = (
    meta.router,
    cluster.router,
    auth.router,
    users.router,
    devices.router,
    subjects.router,
    fingerprints.router,
    sessions.router,
    estimators.router,
    imu_calibration.router,
    gp_learning.router,
    trials.router,
    models.router,
    reports.router,
    viewer.router,
    uploads.router,
    streams.router,
    audit.router,
)

__all__ = ["ROUTERS", "Uploads", "install_error_handlers"]
