"""drapebench.diagnose: each term's value and per-vertex gradient norm, and a non-finite term named."""

import pytest
import torch

from drapebench.diagnose import term_table


def test_each_term_s_value_and_per_vertex_gradient():
    x = torch.zeros(2, 5, 3, dtype=torch.float64)
    x[1, 4, 2] = 1.0
    weights = torch.arange(1.0, 6.0, dtype=torch.float64)  # (V,): vertex v pulled with v+1 newtons along z
    table = term_table(lambda y: {"gravity": (weights[:, None] * y[..., 2:]).sum(), "spring": 0.5 * y.square().sum()}, x)
    assert list(table["term"]) == ["gravity", "spring", "total"]
    g = table.set_index("term")
    assert g.loc["gravity", "value"] == pytest.approx(5.0) and g.loc["spring", "value"] == pytest.approx(0.5)
    assert g.loc["gravity", "grad_mean"] == pytest.approx(3.0) and g.loc["gravity", "grad_max"] == pytest.approx(5.0)
    assert g.loc["gravity", "grad_median"] == pytest.approx(3.0)
    assert g.loc["spring", "grad_max"] == pytest.approx(1.0) and g.loc["spring", "grad_mean"] == pytest.approx(0.1)
    assert g.loc["total", "value"] == pytest.approx(5.5) and g.loc["total", "grad_max"] == pytest.approx(6.0)


def test_a_non_finite_term_is_named():
    x = torch.zeros(4, 3)
    with pytest.raises(ValueError, match="'broken' is not finite"):
        term_table(lambda y: {"fine": y.sum(), "broken": (y / 0.0).sum()}, x)
