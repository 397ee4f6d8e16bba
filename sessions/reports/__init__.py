"""Reports of a stopped session: its summary (:mod:`.summary`), a PDF report (:mod:`.pdf`), a CSV of its
estimates (:mod:`.estimates_csv`), and export jobs with progress (:mod:`.jobs`)."""

from gaitscope.sessions.reports.estimates_csv import CSV_COLUMNS, write_estimates_csv
from gaitscope.sessions.reports.jobs import ExportJobs
from gaitscope.sessions.reports.pdf import render_pdf
from gaitscope.sessions.reports.summary import SETTING_NAMES, TrialData, read_trial, session_summary, setting_text

__all__ = [
    "CSV_COLUMNS",
    "SETTING_NAMES",
    "ExportJobs",
    "TrialData",
    "read_trial",
    "render_pdf",
    "session_summary",
    "setting_text",
    "write_estimates_csv",
]
