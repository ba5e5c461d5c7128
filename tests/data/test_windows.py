"""Windows of frames: exactly the windows that fit, seeded shuffling, batches covering each window once."""

import numpy as np
import pytest

from drapebench.data import Windows


@pytest.mark.parametrize("length, stride, first", [(3, 1, 1), (1, 1, 0), (4, 2, 0), (10, 1, 0)])
def test_windows_are_exactly_those_that_fit(length, stride, first):
    n_frames = [5, 3, 10, 12]
    w = Windows.over(n_frames, length, stride, first)
    expected = [(i, t) for i, n in enumerate(n_frames) for t in range(first, n - length + 1, stride)]
    assert [tuple(r) for r in w.index] == expected and w.length == length
    assert (w.index[:, 1] >= first).all() and (w.index[:, 1] + length <= np.take(n_frames, w.index[:, 0])).all()
    if stride == 1:  # every frame from `first` on of a long-enough sequence is in some window
        for i, n in enumerate(n_frames):
            starts = w.index[w.index[:, 0] == i, 1]
            covered = {t + k for t in starts for k in range(length)}
            assert covered == (set(range(first, n)) if n >= first + length else set())


def test_order_is_seeded_and_changes_with_the_epoch():
    w = Windows.over([50, 60], 3)
    a, b = w.order(seed=1, epoch=0), w.order(seed=1, epoch=0)
    assert np.array_equal(a, b) and sorted(a) == list(range(len(w)))
    assert not np.array_equal(a, w.order(seed=1, epoch=1)) and not np.array_equal(a, w.order(seed=2, epoch=0))


def test_batches_cover_every_window_once_per_epoch():
    w = Windows.over([7, 9], 2)
    batches = list(w.batches(4, seed=0))
    assert [len(b) for b in batches] == [4, 4, 4, 2]
    rows = np.concatenate(batches)
    assert sorted(map(tuple, rows)) == sorted(map(tuple, w.index))
    assert [len(b) for b in w.batches(4, seed=0, drop_last=True)] == [4, 4, 4]


def test_bad_windows_are_rejected():
    with pytest.raises(ValueError, match="no window of 6 frames"):
        Windows.over([5, 4], 6)
    with pytest.raises(ValueError, match="length >= 1"):
        Windows.over([5], 0)
    with pytest.raises(ValueError, match="batch_size"):
        next(Windows.over([5], 2).batches(0, seed=0))
