"""Body model (SMPL-format LBS), the Anny bake, synthetic motions and body sequences."""

from drapebench.body.lbs import axis_angle_to_matrix, inverse_lbs, lbs, matrix_to_axis_angle
from drapebench.body.model import BodyModel, BodyOutput, load_body
from drapebench.body.motions import MOTIONS
from drapebench.body.sequence import BodySequence, make_sequence

__all__ = [
    "MOTIONS",
    "BodyModel",
    "BodyOutput",
    "BodySequence",
    "axis_angle_to_matrix",
    "inverse_lbs",
    "lbs",
    "load_body",
    "make_sequence",
    "matrix_to_axis_angle",
]
