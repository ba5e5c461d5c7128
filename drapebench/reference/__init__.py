"""Physics-based reference drapes on Newton (VBD / Style3D cloth against the animated body), cached.

``simulate(garment, seq, body, material, solver="vbd")`` -> (T, V, 3); the material mapping and its
approximations are documented in :mod:`drapebench.reference.materials`, the schedule (start, settling,
collider, pins) in :mod:`drapebench.reference.simulator`. Newton/warp are imported only when a
simulation actually runs (not for cache hits); the settings alone import no torch (each export is imported at first use).
"""

from drapebench.lazy import exports

_EXPORTS = {
    "SOLVERS": "settings", "SimSettings": "settings",
    **dict.fromkeys(("GarmentInsideBody", "GarmentLeftBody", "SimulationDiverged", "SimulationRecord", "reference_path", "simulate",
                     "simulate_record"), "simulator"),
}  # fmt: skip
__getattr__ = exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
