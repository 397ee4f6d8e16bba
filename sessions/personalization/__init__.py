"""Personalized gait models: a subject's gait fingerprint (seed 004) calibrated from a walk, versioned,
compared, promoted and rolled back (``docs/dashboard.md``, "Personalized models"); and a subject's
speed-change intent model (seed 001's step-length model fitted on a walk, or the iSCI variant;
:mod:`gaitscope.sessions.personalization.intent_model`)."""
