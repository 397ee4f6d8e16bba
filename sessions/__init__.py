"""gaitscope sessions: everything around the estimators, one subpackage per concept.

- ``schema``: every message that crosses a socket or a file; ``store``: subjects, sessions, trials and
  events in SQL; ``estimation``: sensor frames to gait states (the one path live, review and imports
  share); ``errors``, ``files``: shared helpers.
- ``formats/``: replay CSV, LocoHub, MCAP recordings, model files, uploaded-log imports.
- ``live/``: frame sources, the session runtime, its subscribers, the session manager, the disk guard.
- ``review/``: re-runs of recorded trials.
- ``synth/``: the virtual cohort and simulated sensors.
- ``offline/``: training, cross-validation, the replay command, the benchmark.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gaitscope.sessions.errors import DataFormatError
    from gaitscope.sessions.formats.locohub import read_table, write_table
    from gaitscope.sessions.formats.models import default_model_path, load_model, save_model
    from gaitscope.sessions.formats.replay_io import ReplayInput, ReplayOutput, read_replay_csv, write_replay_output

#: Where each name of :data:`__all__` lives: imported on first use (PEP 562), so that importing one
#: subpackage (``gaitscope.sessions.schema``, say) does not import pandas and the LocoHub reader with it.
_LAZY = {
    "DataFormatError": "gaitscope.sessions.errors",
    "ReplayInput": "gaitscope.sessions.formats.replay_io",
    "ReplayOutput": "gaitscope.sessions.formats.replay_io",
    "default_model_path": "gaitscope.sessions.formats.models",
    "load_model": "gaitscope.sessions.formats.models",
    "read_replay_csv": "gaitscope.sessions.formats.replay_io",
    "read_table": "gaitscope.sessions.formats.locohub",
    "save_model": "gaitscope.sessions.formats.models",
    "write_replay_output": "gaitscope.sessions.formats.replay_io",
    "write_table": "gaitscope.sessions.formats.locohub",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'gaitscope.sessions' has no attribute {name!r}")


__all__ = [
    "DataFormatError",
    "ReplayInput",
    "ReplayOutput",
    "default_model_path",
    "load_model",
    "read_replay_csv",
    "read_table",
    "save_model",
    "write_replay_output",
    "write_table",
]
