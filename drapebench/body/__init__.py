"""Body model (SMPL-format LBS), the Anny bake, synthetic motions and body sequences, and the fields
learned over the canonical body (diffused skinning, signed distance)."""

from drapebench.body.canonical_sdf import BODY_SDF_DEFAULTS, BodySDF, fit_body_sdf
from drapebench.body.diffused import DIFFUSED_DEFAULTS, DiffusedBody, diffused_targets, fit_diffused_body
from drapebench.body.lbs import axis_angle_to_matrix, inverse_lbs, lbs, matrix_to_axis_angle
from drapebench.body.model import BodyModel, BodyOutput, load_body
from drapebench.body.motions import MOTIONS
from drapebench.body.sequence import BodySequence, make_sequence

__all__ = [
    "BODY_SDF_DEFAULTS",
    "DIFFUSED_DEFAULTS",
    "BodySDF",
    "DiffusedBody",
    "diffused_targets",
    "fit_body_sdf",
    "fit_diffused_body",
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
