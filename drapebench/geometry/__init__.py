"""Mesh topology, per-element operations and garment-body proximity."""

from drapebench.geometry.ops import corners, dihedral_angles, edge_lengths, face_areas, face_normals, vertex_normals
from drapebench.geometry.topology import Topology, get_topology

__all__ = ["Topology", "corners", "dihedral_angles", "edge_lengths", "face_areas", "face_normals", "get_topology", "vertex_normals"]
