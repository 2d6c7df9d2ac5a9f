"""Wrap checks, unwrapping around the wraps only, and guided unwrapping, against plain rules.

The demodulator checks every map for wraps (pairs of trusted neighbours more than pi
apart) with a shortcut or two, unwraps the guide only in the rectangle around its wraps,
and moves the other maps by whole turns towards the scaled guide in place. Each is
compared here with the rule written plainly, or with the whole map unwrapped.
"""

from __future__ import annotations

import numpy as np
import pytest

from holoview.processing.maps import phase_maps
from holoview.processing.maps.phase_maps import COARSE_SIDE, unwrap_in_space, wrapped_inside
from holoview.processing.maps.unwrap import (
    EDGE,
    has_wraps,
    unwrap_guided,
    unwrap_spatial,
    wrap,
    wrap_bounds,
)


def plain_pairs(phase: np.ndarray, mask: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of trusted neighbours more than pi apart, along rows and along columns."""
    jump_x = np.abs(np.diff(phase, axis=1)) > np.pi
    jump_y = np.abs(np.diff(phase, axis=0)) > np.pi
    if mask is not None:
        jump_x &= mask[:, 1:] & mask[:, :-1]
        jump_y &= mask[1:] & mask[:-1]
    return jump_x, jump_y


def test_wrap_checks_follow_the_plain_rule() -> None:
    rng = np.random.default_rng(240)
    found = 0
    for _ in range(2000):
        shape = tuple(int(n) for n in rng.integers(1, 12, 2))
        scale = rng.choice([0.5, 1.2, 2.0, 3.0, 6.0])
        phase = rng.uniform(-scale, scale, shape)
        if rng.random() < 0.5:
            phase = wrap(phase)  # within pi, as the demodulator's are; else any phase
        phase = phase.astype(np.float32 if rng.random() < 0.5 else np.float64)
        mask = None if rng.random() < 0.3 else rng.random(shape) < rng.uniform(0.3, 1)
        jump_x, jump_y = plain_pairs(phase, mask)
        assert has_wraps(phase, mask) == bool(jump_x.any() or jump_y.any())
        bounds = wrap_bounds(phase, mask)
        if not (jump_x.any() or jump_y.any()):
            assert bounds is None
            continue
        found += 1
        rows, cols = np.zeros(shape[0], bool), np.zeros(shape[1], bool)
        r, c = np.nonzero(jump_x)
        rows[r], cols[c], cols[c + 1] = True, True, True
        r, c = np.nonzero(jump_y)
        rows[r], rows[r + 1], cols[c] = True, True, True
        r, c = np.flatnonzero(rows), np.flatnonzero(cols)
        assert bounds == (r[0], r[-1], c[0], c[-1])
    assert found > 500


def whole_map(phase: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The whole map unwrapped, coarse to fine (the rule before regions)."""
    decimate = max(1, min(phase.shape) // COARSE_SIDE)
    while True:
        unwrapped, _ = unwrap_spatial(phase, mask, decimate=decimate)
        if decimate == 1 or not wrapped_inside(unwrapped, mask):
            return unwrapped
        decimate //= 2


def bumps(shape: tuple[int, int], centres: list[tuple[float, float]], height: float) -> np.ndarray:
    y, x = np.mgrid[: shape[0], : shape[1]].astype(np.float64)
    return sum(
        (height * np.exp(-((y - cy) ** 2 + (x - cx) ** 2) / (2 * 9.0**2)) for cy, cx in centres),
        np.zeros(shape),
    )


@pytest.mark.parametrize(
    ("centres", "region"),
    [
        ([(120, 100)], True),  # inside: only its rectangle
        ([(8, 200)], True),  # at the top edge: the rectangle meets the rest on three sides
        ([(30, 30), (200, 210)], False),  # far apart: the rectangle is most of the map
    ],
)
@pytest.mark.parametrize("hole", [False, True])
def test_unwrapping_around_the_wraps_equals_the_whole_map(
    centres: list[tuple[float, float]], region: bool, hole: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    shape = (240, 240)
    rng = np.random.default_rng(241)
    truth = bumps(shape, centres, 14.0) + 0.4 * np.sin(np.arange(240) / 40.0)[None, :]
    phase = wrap(truth + rng.normal(0, 0.05, shape)).astype(np.float32)
    mask = np.ones(shape, bool)
    mask[:2], mask[-2:], mask[:, :2], mask[:, -2:] = False, False, False, False
    if hole:  # untrusted pixels across the wraps
        mask[115:125, 60:140] = False
        mask[:, 195:205] = False
    kept = phase.copy()
    unwrapped_shapes = []

    def spy(p: np.ndarray, m: np.ndarray, *, decimate: int = 1) -> tuple[np.ndarray, bool]:
        unwrapped_shapes.append(p.shape)
        return unwrap_spatial(p, m, decimate=decimate)

    monkeypatch.setattr(phase_maps, "unwrap_spatial", spy)
    ours, changed = unwrap_in_space(phase, mask)
    np.testing.assert_array_equal(phase, kept)
    assert changed and ours.dtype == np.float32
    assert (unwrapped_shapes[0] != shape) == region
    monkeypatch.undo()
    plain = whole_map(phase, mask)
    turns = np.round((ours - plain) / (2 * np.pi))[mask]
    assert np.all(turns == turns[0])
    np.testing.assert_allclose((ours - plain - 2 * np.pi * turns[0])[mask], 0, atol=1e-5)
    # and it is the truth, up to one turn, away from the map's edge (EDGE pixels: a
    # non-periodic frame's field is not trusted to be continuous there)
    inner = mask.copy()
    inner[:EDGE], inner[-EDGE:], inner[:, :EDGE], inner[:, -EDGE:] = False, False, False, False
    offset = np.round(np.median((ours - truth)[inner]) / (2 * np.pi)) * 2 * np.pi
    assert np.abs(ours - truth - offset)[inner].max() < 0.5
    assert not wrapped_inside(ours, mask)


def test_guided_unwrapping_follows_the_plain_rule() -> None:
    """Each pixel moved by whole turns to within pi of the scaled guide plus the constant
    (the circular mean of the wrapped difference over every 4th row and column)."""
    rng = np.random.default_rng(242)
    y, x = np.mgrid[:96, :120].astype(np.float64)
    guide = 4.0 * np.exp(-((x - 60) ** 2 + (y - 48) ** 2) / (2 * 20.0**2))
    for scale in (1.0, 2.5, 0.4):
        truth = scale * guide + 1.3 + rng.normal(0, 0.1, guide.shape)
        phase = wrap(truth).astype(np.float32)
        mask = rng.random(guide.shape) > 0.2
        ours = unwrap_guided(phase, guide.astype(np.float32), mask, scale=scale)
        g = guide.astype(np.float32) * np.float32(scale)
        difference = wrap(phase - g)
        constant = np.angle(np.mean(np.exp(1j * difference[::4, ::4][mask[::4, ::4]])))
        plain = g + constant + wrap(difference - constant)
        assert ours.dtype == np.float32
        np.testing.assert_allclose(ours, plain, atol=2e-5)
        np.testing.assert_allclose(
            np.round((ours - phase) / (2 * np.pi)) * 2 * np.pi, ours - phase, atol=2e-5
        )
