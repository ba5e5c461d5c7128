"""Fidelity of the baked bodies against Anny's own forward pass (slow: Anny's cold start)."""

import numpy as np
import pytest
import torch

from drapebench.body import axis_angle_to_matrix, load_body
from drapebench.body.bake import JOINT_NAMES, TOPOLOGIES, _group_of_bones, sample_phenotypes
from drapebench.body.limits import JOINT_LIMITS

pytestmark = pytest.mark.slow
anny = pytest.importorskip("anny")

HANDS_FEET = ["left_wrist", "right_wrist", "left_ankle", "right_ankle", "left_foot", "right_foot"]


@pytest.fixture(scope="module", params=list(TOPOLOGIES))
def pair(request):
    from drapebench.cache import cache_dir
    import os

    os.environ.setdefault("ANNY_CACHE_DIR", str(cache_dir("anny")))
    model = anny.Anny(topology=TOPOLOGIES[request.param]).to(torch.float64)
    return load_body(request.param, dtype=torch.float64), model


def _project_betas(body, verts):
    sd = body.shapedirs.reshape(-1, body.n_betas)
    return torch.linalg.lstsq(sd, (verts - body.v_template).reshape(len(verts), -1).T).solution.T


def test_pca_reconstructs_held_out_phenotypes(pair):
    body, model = pair
    kw = {k: torch.as_tensor(v) for k, v in sample_phenotypes(10, seed=123).items()}  # not the bake's seed
    with torch.no_grad():
        ref = model(phenotype_kwargs=kw)["vertices"]
    rec = body.shaped(_project_betas(body, ref))[0]
    assert (rec - ref).norm(dim=-1).mean() < 3e-3


def test_posed_body_matches_anny(pair):
    body, model = pair
    labels = list(model.bone_labels)
    _, drivers = _group_of_bones(labels)
    rng = np.random.default_rng(0)
    lo, hi = JOINT_LIMITS[..., 0], JOINT_LIMITS[..., 1]
    lo, hi = np.clip(lo, -0.8, 0.8), np.clip(hi, -0.8, 0.8)  # random poses within limits, moderate range
    pose = torch.as_tensor(rng.uniform(lo, hi, (20, 22, 3)))
    kw = {k: torch.as_tensor(v) for k, v in sample_phenotypes(10, seed=321).items()}
    with torch.no_grad():
        betas = _project_betas(body, model(phenotype_kwargs=kw)["vertices"])
    keep = ~np.isin(body.weights.numpy().argmax(1), [JOINT_NAMES.index(n) for n in HANDS_FEET])
    R = axis_angle_to_matrix(pose)
    deltas = torch.eye(4, dtype=torch.float64).repeat(20, len(labels), 1, 1)
    deltas[:, drivers, :3, :3] = R
    errors = []
    for i in range(10):
        with torch.no_grad():
            ref = model(pose_parameters=deltas, phenotype_kwargs={k: v[i : i + 1].expand(20) for k, v in kw.items()})
        ours = body.forward(betas[i : i + 1], pose).vertices
        errors.append((ours - ref["vertices"]).norm(dim=-1)[:, keep].mean().item())
    assert np.mean(errors) < 5e-3, f"mean vertex error {np.mean(errors) * 1e3:.2f} mm"
