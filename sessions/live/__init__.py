"""Live sessions: frame sources (simulated, replay, device), the session runtime and its subscribers,
the manager of running sessions, and the disk guard."""
