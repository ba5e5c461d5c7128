"""Cloth material, energies and their validation."""

from drapebench.physics.energies import (
    bending_energy,
    collision_aware_kext,
    collision_energy,
    deformation_gradient,
    gravity_energy,
    green_strain,
    hinge_collision_energy,
    inertia_energy,
    inextensibility_energy,
    laplacian,
    laplacian_smoothness,
    pin_energy,
    restrain_energy,
    ring_covariance,
    stvk_energy,
)
from drapebench.physics.material import Material
from drapebench.physics.terms import energy_terms
from drapebench.physics.validation import MeshStateReport, validate_mesh_state

__all__ = [
    "Material",
    "MeshStateReport",
    "bending_energy",
    "collision_aware_kext",
    "collision_energy",
    "deformation_gradient",
    "energy_terms",
    "gravity_energy",
    "green_strain",
    "hinge_collision_energy",
    "inertia_energy",
    "inextensibility_energy",
    "laplacian",
    "laplacian_smoothness",
    "pin_energy",
    "restrain_energy",
    "ring_covariance",
    "stvk_energy",
    "validate_mesh_state",
]
