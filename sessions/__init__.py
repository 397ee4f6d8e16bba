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

from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.locohub import read_table, write_table
from gaitscope.sessions.formats.models import default_model_path, load_model, save_model
from gaitscope.sessions.formats.replay_io import ReplayInput, ReplayOutput, read_replay_csv, write_replay_output

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
