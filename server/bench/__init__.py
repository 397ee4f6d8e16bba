"""Benchmarks and the harness that starts a real server: ``gaitscope loadbench [--soak]`` and the tests
that need a server in a subprocess. Nothing here is imported by the running server."""
