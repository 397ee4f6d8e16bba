"""Compile every numba kernel once, at install, so that no server, replay or test compiles one while it works.

The estimators' kernels (``estimators/_kernels.py``, ``_batch.py``, ``_lock_batch.py``, ``_sdre_kernel.py``,
``_fp_kernel.py``, the GP filters) and the replay CSV reader's (``sessions/formats/_fastcsv.py``) are
``@njit(cache=True)``: compiled at their first call, then loaded from ``__pycache__``. The server compiles the
live sessions' kernels before it answers (:func:`gaitscope.sessions.live.warmup.warm_up`), but on a fresh install
that took about 40 s of its first start, and the replay's batch path compiled for 30 s inside the first replay.
:func:`warm` runs both ahead: the server's warm-up, then the replay of a short synthetic walk's CSV on both
compiled paths, supervised (the default) and as published (``--as-published``). ``scripts/setup.sh`` runs it
(``gaitscope warm``); with the cache written it takes a second or two. ``tests/sessions/offline/test_warm.py``
checks that a replay after it compiles nothing new (:func:`compiled`), ``tests/sessions/live/test_warmup.py`` the
same of sessions.
"""

from __future__ import annotations

import importlib
import pkgutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

__all__ = ["WARM_STRIDES", "compiled", "warm"]

#: Strides of the synthetic walk the replay paths run (1.2 m/s, level): enough for the phase EKF to lock.
WARM_STRIDES = 12

_PACKAGES = ("gaitscope.estimators", "gaitscope.sessions.formats")


def warm(say: Callable[[str], None] = lambda _: None) -> dict[str, float]:
    """Compile (or load from numba's cache) every kernel a session or a replay calls; ``say`` is told each
    part before it runs.

    Returns:
        The seconds each part took (``sessions``, ``replay``), compiling included.
    """
    from gaitscope.estimators.pipeline import PipelineConfig
    from gaitscope.sessions.formats.models import default_model_path, load_model
    from gaitscope.sessions.live.warmup import warm_up
    from gaitscope.sessions.offline.replay import replay_file
    from gaitscope.sessions.synth.trials import replay_columns, sensor_trial

    took: dict[str, float] = {}
    t0 = time.perf_counter()
    model, _ = load_model(default_model_path())
    say("the live sessions' estimators (the server's warm-up)")
    warm_up(model)
    took["sessions"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    say("the replay, supervised and batch")
    sensors, leg, mass = sensor_trial([(1.2, 0.0, WARM_STRIDES)])
    config = PipelineConfig(leg_length=leg, body_mass_kg=mass)
    with tempfile.TemporaryDirectory(prefix="gaitscope-warm-") as d:
        trial = Path(d) / "walk.csv"
        replay_columns(sensors).to_csv(trial, index=False, float_format="%.6f")
        for supervised in (True, False):
            replay_file(trial, Path(d) / f"out-{supervised}.csv", model, config, supervised=supervised)
    took["replay"] = time.perf_counter() - t0
    return took


def compiled() -> dict[str, frozenset[str]]:
    """Each numba kernel of gaitscope's packages (module and name) and the signatures it has in this process,
    compiled or loaded from the cache (a kernel called only from other kernels has none of its own when
    its callers were loaded from the cache)."""
    from numba.core.registry import CPUDispatcher

    out = {}
    for package in _PACKAGES:
        pkg = importlib.import_module(package)
        for info in pkgutil.iter_modules(pkg.__path__, f"{package}."):
            module = importlib.import_module(info.name)
            for name, obj in vars(module).items():
                if isinstance(obj, CPUDispatcher) and obj.__module__ == module.__name__:
                    out[f"{info.name}.{name}"] = frozenset(str(sig) for sig in obj.signatures)
    return out
