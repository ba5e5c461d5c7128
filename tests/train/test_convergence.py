"""The training time to convergence that GAPS Table 4 reports (drapebench.train.convergence)."""

import numpy as np
import pytest

from drapebench.train.convergence import converged_seconds, converged_step


def test_an_exponential_decay_converges_where_its_drop_is_95_percent_done():
    steps = np.arange(1000)
    loss = 1.0 + np.exp(-steps / 50.0)  # within 5 % of the first window's drop near step 150, plus the window's lag
    s = converged_step(loss)
    assert 150 < s < 230
    assert converged_step(loss, tolerance=0.01) > s  # a tighter criterion converges later


def test_a_loss_still_falling_at_the_end_has_not_converged_before_the_end():
    loss = np.linspace(10.0, 1.0, 400)
    assert converged_step(loss) > 0.9 * len(loss)
    assert converged_step(np.full(50, 3.0)) == 50  # nothing dropped: no earlier step to name
    noisy = np.r_[np.full(100, 5.0), np.full(400, 1.0)] + np.random.default_rng(0).normal(0, 0.01, 500)
    assert 100 < converged_step(noisy) < 140  # the step down, not a noise excursion at the end


def test_converged_seconds_scales_the_training_time_by_the_steps(tmp_path):
    csv = tmp_path / "losses.csv"
    csv.write_text("step,loss\n" + "\n".join(f"{i + 1},{v}" for i, v in enumerate(np.r_[np.full(50, 4.0), np.full(150, 1.0)])))
    assert converged_seconds(csv, 200.0) == pytest.approx(200.0 * converged_step(np.r_[np.full(50, 4.0), np.full(150, 1.0)]) / 200)
    (tmp_path / "empty.csv").write_text("")
    assert converged_seconds(tmp_path / "empty.csv", 0.01) is None  # a run with zero epochs
    with pytest.raises(ValueError, match="finite"):
        converged_step(np.array([1.0, np.nan]))


def test_a_step_down_converges_at_the_first_step_whose_window_holds_only_the_new_level():
    loss = np.r_[np.full(50, 4.0), np.full(150, 1.0)]
    assert converged_step(loss) == 60  # window 10: steps 51-60 are the first window at the final level
