"""Review of recorded and uploaded trials: re-runs through the estimators."""
