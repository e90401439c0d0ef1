"""Confirmation of new landmarks: real ones confirmed after N hits, clutter dropped, bad input."""
import numpy as np
import pytest

from helpers.association.landmark_confirmation import confirm_landmarks, confirmation_sequence


def test_sequence_is_seeded_and_labelled():
    a, b = confirmation_sequence(3), confirmation_sequence(3)
    assert all(np.array_equal(x, y) for x, y in zip(a.frames, b.frames))
    for r, Y, src in zip(a.robot, a.frames, a.sources):
        assert Y.shape == (2, src.size)
        real = src >= 0
        assert np.all(np.abs(Y[:, real].T - a.landmarks[src[real]]) < 6 * a.meas_sigma)
        assert np.all(np.hypot(*(Y[:, ~real].T - r).T) <= a.max_range + 1e-9)
        assert np.count_nonzero(~real) == 2


@pytest.mark.parametrize("seed", range(4))
def test_real_landmarks_confirmed_clutter_never(seed):
    seq = confirmation_sequence(seed, n_frames=10, n_clutter=2)
    tracks, map_src = confirm_landmarks(seq, n_confirm=3, n_miss=2)
    new = np.flatnonzero(~seq.known)
    for j in new:
        frames_seen = sum(j in s for s in seq.sources)
        confirmed = [t for t in tracks if t.source == j and t.status == "confirmed"]
        if frames_seen >= 3:
            assert confirmed and confirmed[0].hits == 3
    assert not any(t.source < 0 and t.status == "confirmed" for t in tracks)
    assert np.all(map_src >= 0) and np.array_equal(np.sort(map_src[:seq.known.sum()]), np.flatnonzero(seq.known))
    for t in tracks:
        if t.status == "dropped":
            assert t.misses == 2 and t.end > t.birth
        if t.status == "tentative":
            assert t.birth >= len(seq.frames) - 2                      # only the last frames are pending


def test_without_confirmation_clutter_enters_the_map():
    seq = confirmation_sequence(0, n_clutter=3)
    _, map_src = confirm_landmarks(seq, n_confirm=1)
    assert np.sum(map_src < 0) >= 20


def test_bad_inputs():
    with pytest.raises(ValueError, match="n_known"):
        confirmation_sequence(0, n_landmarks=3, n_known=4)
    with pytest.raises(ValueError, match="p_detect"):
        confirmation_sequence(0, p_detect=1.5)
    with pytest.raises(ValueError, match="max_range"):
        confirmation_sequence(0, max_range=-1.0)
    with pytest.raises(ValueError, match="n_confirm"):
        confirm_landmarks(confirmation_sequence(0), n_confirm=0)
    with pytest.raises(ValueError, match="n_miss"):
        confirm_landmarks(confirmation_sequence(0), n_miss=0)
