"""Stateful fuzzing of every role (issue 29)."""
