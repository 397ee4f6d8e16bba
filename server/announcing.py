"""The uvicorn server ``gaitscope serve`` runs: it says where it serves once it listens, not before."""

from __future__ import annotations

import socket

import uvicorn

__all__ = ["AnnouncingServer"]


class AnnouncingServer(uvicorn.Server):
    """:class:`uvicorn.Server` that prints ``line`` once its sockets listen (after the app's start-up): a
    URL printed before then did not answer yet (the first start printed it 20 s before it served)."""

    def __init__(self, config: uvicorn.Config, line: str):
        super().__init__(config)
        self.line = line

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        await super().startup(sockets)
        if self.started:
            print(self.line, flush=True)
