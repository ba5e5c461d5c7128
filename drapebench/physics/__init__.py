"""Cloth material, energies and their validation (each imported at first use: the material alone imports no torch)."""

from drapebench.lazy import exports

_EXPORTS = {
    **dict.fromkeys(("bending_energy", "collision_aware_kext", "collision_energy", "deformation_gradient", "gravity_energy",
                     "green_strain", "hinge_collision_energy", "inertia_energy", "inextensibility_energy", "laplacian",
                     "laplacian_smoothness", "pin_energy", "restrain_energy", "ring_covariance", "stvk_energy"), "energies"),
    "Material": "material", "energy_terms": "terms", "MeshStateReport": "validation", "validate_mesh_state": "validation",
}  # fmt: skip
__getattr__ = exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
