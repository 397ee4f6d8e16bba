"""``/api/audit``: the audit trail for admins: a page of entries, the CSV of all that match, the chain's check.

Every route is the admin's (``allow("admin")``). The filters are :class:`gaitscope.sessions.schema.AuditQuery` as query
parameters (an unknown parameter is refused, 422). Exporting the CSV is itself audited (``audit.export``).
"""

from __future__ import annotations

import datetime as dt
from typing import Annotated

from fastapi import APIRouter, Query
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import StreamingResponse

from gaitscope.server.auth import Who, allow
from gaitscope.server.routes.common import Ctx
from gaitscope.sessions import schema
from gaitscope.sessions.audit.export import csv_chunks

router = APIRouter(prefix="/api")

Filters = Annotated[schema.AuditQuery, Query()]
#: The caller, who must be an admin (for the routes that write who they are into the trail).
Admin = Annotated[Who, allow("admin")]


@router.get("/audit", dependencies=[allow("admin")])
def list_audit(q: Filters, c: Ctx) -> list[schema.AuditEntry]:
    """One page of the entries matching the filters, newest first (``limit`` entries from ``offset``)."""
    return c.audit.list(q)


@router.get("/audit.csv", response_class=StreamingResponse)
async def export_audit(q: Filters, c: Ctx, who: Admin) -> StreamingResponse:
    """Every entry matching the filters (``limit``/``offset`` ignored) as CSV, oldest first, streamed."""
    filters = q.model_dump(exclude_none=True, exclude={"limit", "offset"})
    await run_in_threadpool(
        c.audit.record, user=who.name, role=who.role, action="audit.export", target="audit", after=filters
    )
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return StreamingResponse(
        csv_chunks(c.audit.iter(q)),
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="gaitscope-audit-{stamp}.csv"'},
    )


@router.get("/audit/verify", dependencies=[allow("admin")])
def verify_audit(c: Ctx) -> schema.AuditVerification:
    """Walk the whole chain (a million entries take some seconds) and say whether it is intact."""
    return c.audit.verify()
