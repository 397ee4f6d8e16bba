"""The table of subjects' intent models (on :data:`gaitscope.sessions.store.Base`; ``0008_intent_models``)."""

from __future__ import annotations

from sqlalchemy import ForeignKey, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from gaitscope.sessions.store import Base


class IntentModelRow(Base):
    """A subject's intent model (one per subject: setting it again replaces it)."""

    __tablename__ = "intent_models"

    subject_id: Mapped[int] = mapped_column(ForeignKey("subjects.id"), primary_key=True)
    variant: Mapped[str] = mapped_column(String(16))
    kappa: Mapped[str] = mapped_column(Text)  # JSON list of 3 floats
    alpha: Mapped[str | None] = mapped_column(Text, nullable=True)  # JSON list of 2 floats
    source: Mapped[str] = mapped_column(String(200))
    source_trial_id: Mapped[int | None] = mapped_column(nullable=True)
    steps: Mapped[int]
    step_rmse_m: Mapped[float | None]
    actor: Mapped[str] = mapped_column(String(128))
    updated_utc: Mapped[str] = mapped_column(String(40))
    note: Mapped[str] = mapped_column(Text)
