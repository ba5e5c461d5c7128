"""Body model (SMPL-format LBS), the Anny bake, synthetic motions and body sequences, and the fields
learned over the canonical body (diffused skinning, signed distance); each export is imported at first use, so
the constants of :mod:`drapebench.body.defaults` alone import no torch. (``lbs`` the function is
``drapebench.body.lbs.lbs``: the submodule's name.)"""

from drapebench.lazy import exports

_EXPORTS = {
    "BODY_SDF_DEFAULTS": "canonical_sdf", "BodySDF": "canonical_sdf", "fit_body_sdf": "canonical_sdf",
    "DIFFUSED_DEFAULTS": "diffused", "DiffusedBody": "diffused", "diffused_targets": "diffused", "fit_diffused_body": "diffused",
    "axis_angle_to_matrix": "lbs", "inverse_lbs": "lbs", "matrix_to_axis_angle": "lbs",
    "BodyModel": "model", "BodyOutput": "model", "load_body": "model", "MOTIONS": "motions",
    "BodySequence": "sequence", "make_sequence": "sequence",
}  # fmt: skip
__getattr__ = exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
