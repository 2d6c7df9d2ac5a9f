"""Displacements between the peaks' maps, measured over frames, and co-registration."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.processing.maps.coregister import MAX_STDERR, DisplacementEstimator
from holoview.processing.maps.map_moves import coregister

SHAPE = (96, 80)
YY, XX = np.mgrid[: SHAPE[0], : SHAPE[1]].astype(float)


def waves(t: float, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """A moving surface of six plane waves (unit amplitude each)."""
    total = np.zeros(np.broadcast(y, x).shape)
    for k in range(6):
        r = np.random.default_rng(k)
        ky, kx = r.uniform(-0.1, 0.1, 2)
        total += np.cos(2 * np.pi * (ky * y + kx * x) - r.uniform(0.5, 2.0) * t + k)
    return total


def frames_of(shifts: list[tuple[float, float]], noise: float, count: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    for t in range(count):
        yield [waves(t, YY - dy, XX - dx) + noise * rng.normal(size=SHAPE) for dy, dx in shifts]


@pytest.mark.parametrize("noise", [0.1, 2.0])
def test_known_shifts_are_measured_to_a_few_hundredths_of_a_pixel(noise: float) -> None:
    truth = [(0.0, 0.0), (0.37, -1.23), (-2.6, 0.15), (0.05, 0.02)]
    estimator = DisplacementEstimator(SHAPE, len(truth))
    for maps in frames_of(truth, noise, 40):
        maps[1][:6] = np.nan  # untrusted rows are left out, not taken as zero height
        estimator.add(maps)
    found = estimator.displacements()
    assert found[0].shift == (0.0, 0.0) and found[0].measured
    for (dy, dx), d in zip(truth[1:], found[1:], strict=True):
        assert d.measured, d
        assert d.shift == pytest.approx((dy, dx), abs=0.05)
        assert max(d.stderr) < MAX_STDERR


def test_maps_of_opposite_sign_give_the_same_shift() -> None:
    estimator = DisplacementEstimator(SHAPE, 2)
    for a, b in frames_of([(0.0, 0.0), (0.8, -0.4)], 0.3, 30):
        estimator.add([a, -2.5 * b])
    d = estimator.displacements()[1]
    assert d.measured
    assert d.shift == pytest.approx((0.8, -0.4), abs=0.05)


def test_noise_alone_or_a_flat_surface_gives_no_shift() -> None:
    rng = np.random.default_rng(7)
    noisy = DisplacementEstimator(SHAPE, 2)
    flat = DisplacementEstimator(SHAPE, 2)
    for _ in range(30):
        noisy.add([rng.normal(size=SHAPE), rng.normal(size=SHAPE)])
        flat.add([np.full(SHAPE, 3e-9), np.full(SHAPE, 3e-9)])
    for estimator in (noisy, flat):
        d = estimator.displacements()[1]
        assert not d.measured and d.shift == (0.0, 0.0)
    assert DisplacementEstimator(SHAPE, 2).displacements()[1].measured is False


def test_reset_forgets_the_frames() -> None:
    estimator = DisplacementEstimator(SHAPE, 2)
    for maps in frames_of([(0.0, 0.0), (1.0, 0.0)], 0.1, 10):
        estimator.add(maps)
    assert estimator.displacements()[1].measured
    estimator.reset()
    assert estimator.frames == 0 and not estimator.displacements()[1].measured


@pytest.mark.parametrize(("method", "tolerance"), [("spline", 0.001), ("cubic", 0.005)])
def test_coregister_moves_a_map_back_and_keeps_untrusted_pixels_untrusted(
    method: str, tolerance: float
) -> None:
    d = (0.4, -1.3)
    reference = waves(0.0, YY, XX)
    moving = waves(0.0, YY - d[0], XX - d[1])
    moving[40, 40] = np.nan
    original = moving.copy()
    back, same = coregister([moving, reference], [d, (0.0, 0.0)], method=method)
    np.testing.assert_array_equal(moving, original)  # input not modified
    inner = (slice(4, -4), slice(4, -4))
    error = np.sqrt(np.nanmean((back - reference)[inner] ** 2))
    assert error < tolerance * np.std(reference)  # waves of 7 pixels and longer
    assert np.sqrt(np.nanmean((moving - reference)[inner] ** 2)) > 10 * error  # it did move
    # back(r) = moving(r + d): the NaN at (40, 40) now spoils the 4 x 4 around (39.6, 41.3)
    assert np.isnan(back[38:42, 40:44]).all()
    assert np.count_nonzero(np.isnan(back[inner])) == 16
    np.testing.assert_array_equal(same, reference.astype(np.float32))
    assert back.dtype == np.float32


def test_whole_pixel_shifts_are_exact_and_leave_the_uncovered_edge_untrusted() -> None:
    moving = waves(0.0, YY - 2.0, XX + 1.0)
    for method in ("spline", "cubic"):
        (back,) = coregister([moving], [(2.0, -1.0)], method=method)
        np.testing.assert_allclose(back[4:-4, 4:-4], waves(0.0, YY, XX)[4:-4, 4:-4], atol=1e-5)
        # back(r) = moving(r + (2, -1)): the last two rows and the first column come
        # from outside the map, and are not made up
        assert np.isnan(back[-2:]).all() and np.isnan(back[:, 0]).all()
        assert np.isfinite(back[:-2, 1:]).all()


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: DisplacementEstimator(SHAPE, 1), "at least 2 maps"),
        (lambda: DisplacementEstimator((4, 40), 2), "too small"),
        (lambda: DisplacementEstimator(SHAPE, 2, reference=2), "reference map 2"),
        (lambda: DisplacementEstimator(SHAPE, 2).add([np.zeros(SHAPE)]), "1 maps given"),
        (
            lambda: DisplacementEstimator(SHAPE, 2).add([np.zeros(SHAPE), np.zeros((8, 8))]),
            "shape (8, 8)",
        ),
        (lambda: coregister([np.zeros(SHAPE)], []), "1 maps but 0 shifts"),
        (lambda: coregister([np.zeros(SHAPE)], [(1, 1)], method="sinc"), "unknown interpolation"),
    ],
)
def test_bad_input_is_named(call, message: str) -> None:
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        call()


def _untrusted(maps: list[np.ndarray], t: int) -> list[np.ndarray]:
    """The maps with untrusted pixels that change from frame to frame and map to map: a
    band of rows that moves, the same number of pixels at other places; two maps share
    the reference's."""
    out = []
    for j, given in enumerate(maps):
        values = given.copy()
        if j in (0, 2):
            values[:4] = np.nan
        else:
            start = (7 * t + 3 * j) % (SHAPE[0] - 4)
            values[start : start + 4] = np.nan
        out.append(values)
    return out


def test_weights_kept_from_earlier_frames_change_no_number() -> None:
    """The pair weights kept by mask (the same count of pixels trusted at other places in
    the frames before) and a frame's reference side shared by maps give the numbers of an
    estimator that saw none of them, to the last bit."""
    truth = [(0.0, 0.0), (0.37, -1.23), (0.0, 0.0), (-2.6, 0.15)]
    frames = [_untrusted(maps, t) for t, maps in enumerate(frames_of(truth, 0.3, 24))]
    fresh = DisplacementEstimator(SHAPE, len(truth), update_every=4)
    for maps in frames:
        fresh.add(maps)
    warm = DisplacementEstimator(SHAPE, len(truth), update_every=4)
    for maps in reversed(frames):  # every mask seen before, in another order
        warm.add(maps)
    for k, maps in enumerate(frames_of(truth, 0.3, 30, seed=2)):  # more masks than are kept
        warm.add(_untrusted(maps, 5 * k + 1))
    warm.reset()
    for maps in frames:
        warm.add(maps)
    expected = [(d.shift, d.stderr, d.measured, d.bins) for d in fresh.displacements()]
    assert [(d.shift, d.stderr, d.measured, d.bins) for d in warm.displacements()] == expected
    assert fresh.displacements()[1].shift == pytest.approx(truth[1], abs=0.1)
