"""Failures of a method on valid input (a diverged simulation or training), as opposed to bad input.

A sweep run with ``on_failure=record`` records such a failure in the run's ``failed.json`` (tables
show the cell as failed, with the message below) and goes on with the other jobs; with the default
``on_failure=stop`` it is raised like any other error.
"""

from __future__ import annotations


class DrapeFailed(RuntimeError):
    """A method could not produce a drape for this scene (it diverged); the message says where and what to change."""


class TrainingDiverged(DrapeFailed):
    """Training produced a non-finite loss or gradient; no trained checkpoint was written."""
