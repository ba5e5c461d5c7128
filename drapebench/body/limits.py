"""Per-joint rotation limits of the 22-joint skeleton, in the body frame.

Frame: Z up, the body faces -Y, +X is the body's left. Each joint's pose is an axis-angle in
world-aligned axes at the rest (A-)pose, so a rotation about +X swings a downward limb backwards
(+Y), about +Y tilts an upward segment towards +X (the body's left), about +Z turns to the left.
Sign conventions that follow (checked in ``tests/body/test_motions.py`` on the baked body):

* hip flexion (thigh forward) is a negative X rotation; knee flexion (shin backwards) positive X;
* spine/neck flexion (bending forwards) is positive X;
* raising the left arm sideways is a negative Y rotation of ``left_shoulder`` (positive for the right);
* shoulder flexion (arm forwards) is negative X; elbow flexion (forearm forwards and up) negative X.

Limits are conservative anatomical ranges (radians); the root (pelvis) is free.
"""

from __future__ import annotations

import numpy as np

from drapebench.body.bake import JOINT_NAMES

_LEFT = {
    # joint: ((xmin, xmax), (ymin, ymax), (zmin, zmax))
    "hip": ((-1.9, 0.5), (-0.8, 0.3), (-0.6, 0.6)),
    "knee": ((0.0, 2.3), (-0.05, 0.05), (-0.15, 0.15)),
    "ankle": ((-0.5, 0.8), (-0.3, 0.3), (-0.3, 0.3)),
    "foot": ((-0.6, 0.4), (-0.05, 0.05), (-0.05, 0.05)),
    "collar": ((-0.3, 0.3), (-0.35, 0.25), (-0.3, 0.3)),
    "shoulder": ((-2.0, 0.8), (-2.2, 0.6), (-1.0, 1.0)),
    "elbow": ((-2.3, 0.0), (-0.2, 0.2), (-0.3, 0.3)),
    "wrist": ((-0.8, 0.8), (-0.5, 0.5), (-0.5, 0.5)),
}
_CENTRE = {
    "pelvis": ((-np.pi, np.pi),) * 3,
    "spine1": ((-0.3, 0.5), (-0.3, 0.3), (-0.35, 0.35)),
    "spine2": ((-0.3, 0.5), (-0.3, 0.3), (-0.35, 0.35)),
    "spine3": ((-0.3, 0.5), (-0.3, 0.3), (-0.35, 0.35)),
    "neck": ((-0.5, 0.6), (-0.4, 0.4), (-0.7, 0.7)),
    "head": ((-0.4, 0.4), (-0.3, 0.3), (-0.5, 0.5)),
}


def _table() -> np.ndarray:
    lim = np.zeros((len(JOINT_NAMES), 3, 2))
    for j, name in enumerate(JOINT_NAMES):
        if name in _CENTRE:
            lim[j] = _CENTRE[name]
            continue
        side, part = name.split("_", 1)
        left = np.array(_LEFT[part])
        if side == "right":  # mirror x -> -x: axis-angle (ax, ay, az) -> (ax, -ay, -az)
            left[1:] = -left[1:, ::-1]
        lim[j] = left
    return lim


JOINT_LIMITS = _table()  # (22, 3, 2) radians: [joint, axis, (min, max)]


def limit_violation(poses: np.ndarray, tol: float = 1e-6) -> np.ndarray:
    """Per-frame, per-joint, per-axis amount (rad) by which ``poses`` (T, 22, 3) exceed the limits."""
    lo, hi = JOINT_LIMITS[..., 0], JOINT_LIMITS[..., 1]
    return np.maximum(lo - poses - tol, 0) + np.maximum(poses - hi - tol, 0)
