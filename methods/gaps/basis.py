"""A smooth output basis for GAPS's network (``method.params.output_basis: laplacian``; beyond the paper, whose
network outputs V x 3 displacements directly): the K lowest-frequency eigenvectors of the template's cotangent
Laplacian, so that the network predicts K x 3 coefficients and every displacement it outputs is smooth.

The eigenproblem is the discrete Laplace-Beltrami operator's, L phi = lambda M phi, with L the template's
cotangent Laplacian (``Topology.laplacian``) and M its lumped vertex areas. The cotangent Laplacian with the
mass matrix and not the uniform graph Laplacian: its modes are the surface's vibration modes whatever the
triangulation, where the graph Laplacian's wavelengths shrink wherever the mesh is denser. The basis is
orthonormal under M normalised to a mean of 1 (Phi^T (M / mean(M)) Phi = I): on a mesh of equal areas that is
Euclidean orthonormality, the dense output's identity basis restricted to smooth fields, so the output layer's
gradients keep the dense layer's scale. Solved once per template in float64 (scipy's ``eigsh``, shift-invert
about a small negative shift) and cached by the mesh's content; cast to the run's dtype where it is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
import torch

from drapebench.cache import Cache
from drapebench.geometry.topology import get_topology

BASES = Cache("gaps_basis", 1)  # bump when the eigenproblem or the stored arrays change
KEYS = ("output_basis", "basis_modes")  # GAPS's keys of the output basis: they change the network, not the loss or the canonical garment


@dataclass(frozen=True)
class LaplacianBasis:
    """vectors (V, K) float64, orthonormal under the lumped mass matrix normalised to mean 1 (``mass``, (V,));
    values (K,) ascending eigenvalues of L phi = lambda M phi (1/m^2; the first 0 on a connected mesh)."""

    vectors: torch.Tensor
    values: torch.Tensor
    mass: torch.Tensor


def laplacian_basis(vertices, faces, modes: int) -> LaplacianBasis:
    """The ``modes`` lowest-frequency eigenvectors of the cotangent Laplacian of the mesh (vertices (V, 3) m, faces
    (F, 3)), cached in ``data/cache/gaps_basis`` by the mesh's content. Raises ValueError unless 1 <= modes < V."""
    x = np.asarray(vertices.detach().cpu() if isinstance(vertices, torch.Tensor) else vertices, dtype=np.float64)
    f = np.asarray(faces.detach().cpu() if isinstance(faces, torch.Tensor) else faces, dtype=np.int64)
    modes = int(modes)
    if not 1 <= modes < len(x):
        raise ValueError(f"gaps parameter basis_modes must be between 1 and the garment's {len(x) - 1} vertices less one, not {modes}")

    def build() -> dict:
        topo = get_topology(x, f, dtype=torch.float64)
        lap = topo.laplacian.coalesce()
        i, v = lap.indices().numpy(), lap.values().numpy()
        L = scipy.sparse.csc_matrix((v, (i[0], i[1])), shape=lap.shape)
        area = topo.vertex_areas.numpy()
        M = scipy.sparse.diags(area).tocsc()
        # shift-invert about -1/(total area): L - sigma M is positive definite, its scale that of the lowest modes
        v0 = np.random.default_rng(0).standard_normal(len(x))  # a fixed start: the same basis on every machine
        values, vectors = scipy.sparse.linalg.eigsh(L, k=modes, M=M, sigma=-1.0 / area.sum(), which="LM", v0=v0)
        order = np.argsort(values)
        values, vectors = values[order], vectors[:, order]
        mass = area / area.mean()
        vectors = vectors / np.sqrt((vectors**2 * mass[:, None]).sum(0))  # eigsh's M-normalisation, made exact, under M / mean(M)
        vectors = vectors * np.sign(vectors[np.abs(vectors).argmax(0), np.arange(modes)])  # each mode's largest entry positive
        return {"vectors": vectors, "values": values, "mass": mass}

    def write(arr: dict, tmp) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arr)

    def read(path) -> dict:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}

    arr = BASES.get_or_build(BASES.path(x, f, modes, prefix="laplacian"), build, write, read)
    return LaplacianBasis(*(torch.as_tensor(arr[k]) for k in ("vectors", "values", "mass")))
