"""gaitscope estimators."""
