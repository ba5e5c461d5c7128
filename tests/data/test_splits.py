"""Seeded splits: disjoint, complete, and the test motions never in training."""

import numpy as np
import pytest

from drapebench.data import check_held_out, split_sequences

MOTIONS = ["walk"] * 10 + ["random"] * 20 + ["kick"] * 4 + ["dance"] * 6


def test_split_is_disjoint_complete_and_seeded():
    s = split_sequences(MOTIONS, seed=0, val_fraction=0.2, test_fraction=0.1, test_motions=("kick",))
    parts = [set(s.train), set(s.val), set(s.test)]
    assert sum(map(len, parts)) == len(MOTIONS) and set.union(*parts) == set(range(len(MOTIONS)))
    assert len(s.val) == round(0.2 * 36) and len(s.test) == 4 + round(0.1 * 36)
    again = split_sequences(MOTIONS, seed=0, val_fraction=0.2, test_fraction=0.1, test_motions=("kick",))
    other = split_sequences(MOTIONS, seed=1, val_fraction=0.2, test_fraction=0.1, test_motions=("kick",))
    assert all(np.array_equal(a, b) for a, b in zip((s.train, s.val, s.test), (again.train, again.val, again.test)))
    assert not np.array_equal(s.val, other.val)


def test_test_motions_never_reach_training():
    s = split_sequences(MOTIONS, seed=3, val_fraction=0.1, test_motions=("kick", "dance"))
    motions = np.array(MOTIONS)
    assert set(motions[s.test]) == {"kick", "dance"} and len(s.test) == 10  # all of them, and only them
    assert not {"kick", "dance"} & (set(motions[s.train]) | set(motions[s.val]))
    with pytest.raises(ValueError, match="no sequence left for training"):
        split_sequences(["kick"] * 3, seed=0, test_motions=("kick",))


def test_bad_fractions_and_leaked_test_motions_are_errors():
    with pytest.raises(ValueError, match="sum < 1"):
        split_sequences(MOTIONS, seed=0, val_fraction=0.6, test_fraction=0.4)
    with pytest.raises(ValueError, match=r"kick \(2 sequences\) appear in the training set"):
        check_held_out(["walk", "kick", "kick"], ("kick", "stress"))
    check_held_out(["walk", "random"], ("kick",))
