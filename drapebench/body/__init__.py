"""Body model (SMPL-format LBS), the Anny bake, synthetic motions and body sequences."""

from drapebench.body.lbs import axis_angle_to_matrix, inverse_lbs, lbs, matrix_to_axis_angle
from drapebench.body.model import BodyModel, BodyOutput, load_body

__all__ = [
    "BodyModel",
    "BodyOutput",
    "axis_angle_to_matrix",
    "inverse_lbs",
    "lbs",
    "load_body",
    "matrix_to_axis_angle",
]
