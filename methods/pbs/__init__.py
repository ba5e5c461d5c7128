"""``pbs``: the physics-based reference simulator (drapebench.reference) as a draping method."""

from methods.pbs.method import PBSMethod

__all__ = ["PBSMethod"]
