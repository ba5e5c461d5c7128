"""Physics-based reference drapes on Newton (VBD / Style3D cloth against the animated body), cached.

``simulate(garment, seq, body, material, solver="vbd")`` -> (T, V, 3); the material mapping and its
approximations are documented in :mod:`drapebench.reference.materials`, the schedule (start, settling,
collider, pins) in :mod:`drapebench.reference.simulator`. Newton/warp are imported only when a
simulation actually runs (not for cache hits).
"""

from drapebench.reference.settings import SOLVERS, SimSettings
from drapebench.reference.simulator import (
    GarmentInsideBody,
    GarmentLeftBody,
    SimulationDiverged,
    SimulationRecord,
    reference_path,
    simulate,
    simulate_record,
)

__all__ = ["SOLVERS", "GarmentInsideBody", "GarmentLeftBody", "SimSettings", "SimulationDiverged", "SimulationRecord", "reference_path", "simulate",
           "simulate_record"]
