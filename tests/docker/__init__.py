"""Tests of the container deployment (docker/)."""
