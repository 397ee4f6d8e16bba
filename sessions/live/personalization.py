"""Fingerprint promotion reaching a running session, as a session extension.

A subject's personalization (the fingerprint of the personalized filter ``fp_ls``) can be promoted or rolled
back while one of their sessions runs (:mod:`gaitscope.server.routes.fingerprints`). The session's log says so,
and its running ``fp_ls`` takes the now active fingerprint itself at its next heel strike
(``personalize``). A session whose stack has no ``fp_ls`` (none was active when it started) keeps its stack:
the event says the change applies from the next session.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitscope.sessions.live.extensions import SessionExtension, SessionHost

__all__ = ["Personalization"]


class Personalization(SessionExtension):
    """The fingerprint a session's ``fp_ls`` runs, and the promotions that reach it.

    Attributes:
        fingerprint: the fingerprint it runs (recorded with each trial, for a re-run); None: none.
    """

    def __init__(self, host: SessionHost, fingerprint: Sequence[float] | None):
        self.host = host
        self.fingerprint = None if fingerprint is None else list(fingerprint)

    def changed(self, text: str, actor: str) -> None:
        """The subject's personalization was promoted or rolled back (``text`` says which): an event in the
        session's log, and the running ``fp_ls`` takes the now active fingerprint at its next heel strike."""
        host = self.host
        active = host.store.active_personalization(host.subject.id, host.session.settings.model)
        fp_ls = next((e for e in host.estimator.stack.estimators if e.name == "fp_ls"), None)
        if fp_ls is None:
            host.event("system", f"{text}; fp_ls is not running here: it applies from the next session", actor=actor)
            return
        if active is None:
            host.event("system", f"{text}; fp_ls keeps its fingerprint until the session ends", actor=actor)
            return
        try:
            fp_ls.personalize(np.array(active.fingerprint))  # type: ignore[attr-defined]
        except ValueError as e:
            host.event("system", f"{text}; fp_ls cannot take it ({e})", actor=actor)
            return
        self.fingerprint = active.fingerprint
        host.event("system", f"{text}; fp_ls takes it at the next heel strike", actor=actor)
