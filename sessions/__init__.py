"""gaitscope sessions."""
