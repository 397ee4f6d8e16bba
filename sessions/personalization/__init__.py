"""Personalized gait models: a subject's gait fingerprint (seed 004) calibrated from a walk, versioned,
compared, promoted and rolled back (``docs/dashboard.md``, "Personalized models")."""
