"""The partial waves' modes and their lock-ins: which (m, f) are fitted, on which comb.

A tone's frequency and radial profile are fitted to lock-ins of every ring at a comb of
:data:`COMB_POINTS` frequencies :data:`COMB_SPACING` resolutions apart
(:func:`~holoview.processing.waves.partial_waves.refine_tone`). Pass 2 of
:mod:`~holoview.headless.waves.analysis` makes them around each candidate tone;
:func:`mode_lock_ins` gives each chosen mode its comb: a candidate's, or one found by a
search around the mode's own (m, f) peak.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from holoview.errors import InputError
from holoview.headless.waves.maps import WaveMaps
from holoview.processing.waves.azimuthal import AzimuthalAccumulator

if TYPE_CHECKING:
    from holoview.headless.waves.analysis import WaveOptions, WaveResults

__all__ = ["COMB_POINTS", "COMB_SPACING", "comb_around", "mode_lock_ins"]

#: Lock-in frequencies per candidate tone, and their spacing in units of 1 / duration.
COMB_POINTS = 9
COMB_SPACING = 0.25

#: Most steps of a comb's spacing either side of a mode's own (m, f) peak that its tone
#: is sought over (:func:`_search`).
SEARCH_HALF_MAX = 64


def _spaced(maps: WaveMaps, frequency: float, half: int) -> np.ndarray:
    """``2 half + 1`` lock-in frequencies a comb's spacing apart centred on ``frequency``,
    Hz (clipped to 0 and Nyquist)."""
    step = COMB_SPACING / max(float(maps.clock.times[-1]), 1e-300)
    offsets = np.arange(-half, half + 1) * step
    spaced: np.ndarray = np.clip(frequency + offsets, 1e-9, 0.5 / maps.clock.interval)
    return spaced


def comb_around(maps: WaveMaps, frequency: float) -> np.ndarray:
    """The lock-in frequencies around a tone, Hz (clipped to 0 and Nyquist)."""
    return _spaced(maps, frequency, COMB_POINTS // 2)


def _search(maps: WaveMaps, frequency: float, bin_hz: float) -> np.ndarray:
    """Lock-in frequencies a comb's spacing apart around a mode's own (m, f) peak, over a
    comb's width or half a bin of the (m, f) spectrum either side (where the tone may lie:
    in a long record a comb is narrower), at most :data:`SEARCH_HALF_MAX` steps, Hz."""
    step = COMB_SPACING / max(float(maps.clock.times[-1]), 1e-300)
    half = max(COMB_POINTS // 2, min(math.ceil(0.5 * bin_hz / step), SEARCH_HALF_MAX))
    return _spaced(maps, frequency, half)


def mode_lock_ins(
    maps: WaveMaps,
    options: WaveOptions,
    results: WaveResults,
    candidates: list[float],
    *,
    combs: list[np.ndarray],
    profiles: np.ndarray,
    kept: list[tuple[np.ndarray, np.ndarray]] | None,
    span: tuple[float, float],
) -> list[tuple[int, float, np.ndarray, np.ndarray]]:
    """The modes to fit (given, or the strongest (m, f) peaks), each with its comb and
    lock-ins, shape (C, R).

    A mode takes its candidate tone's comb (``combs``, their lock-ins ``profiles``, made
    in pass 2) where its own (m, f) peak lies within that comb, or within half a bin of a
    drive's harmonic (exact, where the peak is not: in a long record the comb is
    narrower than a bin). Else it takes the comb around the strongest of its ``m``'s
    lock-ins over a search around its own peak (:func:`_search`), made from pass 2's
    ring samples (``kept``) or, where pass 2 kept none (past
    :data:`~holoview.headless.waves.analysis.KEPT_SAMPLES_BYTES`), in one more pass over
    the maps. E(omega) sums every ``m`` and blends tones closer than about two bins into
    one peak between them (``m = 1`` at 18 Hz and ``m = -1`` at 19 Hz in bins of 0.78 Hz:
    one candidate at 18.2 Hz, around which the 19 Hz tone was fitted at the comb's end,
    18.6 Hz, its amplitude 75 % low), where the (m, f) spectrum tells them apart. A
    comb around the peak alone missed tones in long records, whose combs are narrower
    than the peak's precision (80 s of ``bench_waves``' field: the tone of a plane wave at
    13.87 Hz, at m = -3, 3 and -5, was refused as lying beyond the comb around its
    peak). A mode with no candidate within two bins is a note, not fitted.
    """
    grid, mf = results.grid, results.mf
    assert grid is not None and mf is not None
    bin_hz = float(mf.frequency[1])
    near = 2 * max(bin_hz, results.spectrum.df)  # a candidate's peak, in E(omega)'s bins
    harmonics = set(options.drive_harmonics)
    if options.modes:
        chosen = list(options.modes)
    else:
        chosen = mf.strongest(options.n_modes, f_min=2 * bin_hz)
    modes: list[tuple[int, float, int, np.ndarray | None]] = []  # a candidate's, or a search
    searched: list[np.ndarray] = []
    for m, f in chosen:
        if abs(m) > options.m_max:
            raise InputError(f"mode m={m} is beyond --m-max {options.m_max}")
        distances = [abs(f - c) for c in candidates]
        nearest = int(np.argmin(distances)) if candidates else -1
        if nearest < 0 or distances[nearest] > near:
            results.notes.append(
                f"(m, f) = ({m}, {f:.4g} Hz): no candidate tone near it in E(omega); not fitted"
            )
            continue
        comb = combs[nearest]
        exact = candidates[nearest] in harmonics and distances[nearest] <= 0.5 * bin_hz
        if comb[0] <= f <= comb[-1] or exact:
            modes.append((m, f, nearest * COMB_POINTS, None))
        else:
            searched.append(_search(maps, f, bin_hz))
            start = len(candidates) * COMB_POINTS + sum(g.size for g in searched[:-1])
            modes.append((m, f, start, searched[-1]))
    if searched:
        accumulator = AzimuthalAccumulator(
            grid,
            maps.clock.interval,
            segment=options.segment,
            lock_in=np.concatenate(searched).tolist(),
            span=span,
            workers=options.workers,
            spectrum=False,
        )
        if kept is None:
            for times, block in maps.blocks(options.block):
                accumulator.push_block(block, times)
        else:
            for times, samples in kept:
                accumulator.push_modes(samples.astype(np.complex128), times)
        profiles = np.concatenate([profiles, accumulator.profiles()])
    out, half = [], COMB_POINTS // 2
    for m, f, start, search in modes:
        column = profiles[:, :, m + grid.m_max]
        if search is None:
            comb, first = combs[start // COMB_POINTS], start
        else:  # the comb around the search's strongest lock-in of this m
            power = np.nansum(np.abs(column[start : start + search.size]) ** 2, axis=1)
            centre = int(np.clip(np.argmax(power), half, search.size - 1 - half))
            comb, first = search[centre - half : centre + half + 1], start + centre - half
        out.append((m, f, comb, column[first : first + COMB_POINTS]))
    return out
