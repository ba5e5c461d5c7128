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


class NonFiniteDrape(DrapeFailed):
    """A method's drape has NaN or Inf coordinates; the message names the method, how many frames and the first ones."""

    def __init__(self, method: str, frames: list[int], n_frames: int):
        self.method, self.frames = method, frames
        shown = ", ".join(map(str, frames[:10])) + (f" and {len(frames) - 10} more" if len(frames) > 10 else "")
        super().__init__(f"{method} produced NaN/Inf vertex positions in {len(frames)} of {n_frames} frames (frames {shown}); "
                         "nothing was evaluated. Try the scene in float64 (dtype=float64) or a milder motion or shape.")
