"""gaitscope server."""
