"""gaitscope sessions: data in and out of the estimators.

The virtual cohort and simulated sensors, LocoHub and replay-CSV files, model files, training,
replay and cross-validation. (Subjects, sessions, trials and recording arrive with the dashboard.)
"""

from sessions.errors import DataFormatError
from sessions.locohub import read_table, write_table
from sessions.models import default_model_path, load_model, save_model
from sessions.replay_io import ReplayInput, read_replay_csv, write_replay_output

__all__ = [
    "DataFormatError",
    "ReplayInput",
    "default_model_path",
    "load_model",
    "read_replay_csv",
    "read_table",
    "save_model",
    "write_replay_output",
    "write_table",
]
