"""Partial waves' standard errors against the scatter of seeded fits, and close tones."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import special
from waves_synth import sample

from holoview.errors import InputError
from holoview.headless.waves import analysis
from holoview.headless.waves.analysis import WaveOptions, analyse_waves
from holoview.optics.wave_fields import PartialWave, PartialWaves
from holoview.processing.waves.azimuthal import MFSpectrum
from holoview.processing.waves.clock import frame_clock
from holoview.processing.waves.dispersion import Fluid
from holoview.processing.waves.partial_waves import (
    PartialWaveFit,
    fit_partial_wave,
    refine_tone,
    unsteady_tone,
)

SIZE, PIXEL, FPS, FRAMES = 96, 0.5e-3, 100.0, 256
CENTRE_MAP = (24.3e-3, 22.8e-3)  # map coordinates, m (off the pixel grid)


def _z_scores(fit: PartialWaveFit, outgoing: complex, incoming: complex) -> dict[str, float]:
    """``(fit - truth) / stderr`` of the moduli, the phases and their ratio."""
    return {
        "|out|": (abs(fit.outgoing) - abs(outgoing)) / fit.outgoing_stderr,
        "arg out": float(np.angle(fit.outgoing / outgoing)) / fit.outgoing_phase_stderr,
        "|in|": (abs(fit.incoming) - abs(incoming)) / fit.incoming_stderr,
        "arg in": float(np.angle(fit.incoming / incoming)) / fit.incoming_phase_stderr,
        "in/out": (fit.ratio - abs(incoming) / abs(outgoing)) / fit.ratio_stderr,
    }


def _assert_honest(rows: list[dict[str, float]]) -> None:
    """Every quantity's rms z over the seeds is within 0.8 to 1.25."""
    rms = {name: float(np.sqrt(np.mean([row[name] ** 2 for row in rows]))) for name in rows[0]}
    assert all(0.8 < value < 1.25 for value in rms.values()), rms


def test_hankel_fit_errors_match_the_scatter_over_noise_seeds():
    """Over 150 seeds of ring noise the moduli, phases, ratio and k scatter as their
    standard errors say (rms z 0.8 to 1.25). The covariance had been halved (rms z 1.43
    with k given) and taken at the fitted k, leaving out k's own error, which turns the
    phases (rms z 2.2 to 2.5 with k fitted)."""
    r = np.arange(5e-3, 28e-3, 0.5e-3)
    k, outgoing, incoming = 700.0, 3 - 1j, 1 + 2j
    clean = outgoing * special.hankel1(2, k * r) + incoming * special.hankel2(2, k * r)
    spread = 0.05 * np.sqrt(r[0] / r)  # a ring of radius r averages about 2 pi r pixels
    for fit_k in (False, True):
        rows = []
        for seed in range(150):
            rng = np.random.default_rng(seed)
            noise = spread * (rng.normal(size=r.size) + 1j * rng.normal(size=r.size))
            fit = fit_partial_wave(r, clean + noise, 2, 20.0, k, fit_wavenumber=fit_k)
            rows.append(_z_scores(fit, outgoing, incoming))
            if fit_k:
                rows[-1]["k"] = (fit.wavenumber - k) / fit.wavenumber_stderr
        _assert_honest(rows)


def test_tone_and_hankel_errors_through_lock_ins_match_the_scatter_over_noise_seeds():
    """Rings' series (a partial wave in white noise) through lock-ins at a comb, the tone's
    refinement and the Hankel fit: over 150 seeds the frequency, k, moduli, phases and
    ratio scatter as their standard errors say (rms z 0.8 to 1.25). The frequency's error
    had counted the comb's nine lock-ins as independent, a quarter of a resolution apart
    and nearly the same numbers (rms z 3.0 with 20 rings); times 2 pi t_mean, it is an
    error of the phases too."""
    times = np.arange(FRAMES) / FPS
    weights = np.sin(np.pi * times / times[-1]) ** 2
    r = np.arange(5e-3, 21e-3, 0.5e-3)
    m, frequency, k, outgoing, incoming = 2, 22.13, 760.0, 15e-9 + 0j, 8e-9 + 6e-9j
    profile = outgoing * special.hankel1(m, k * r) + incoming * special.hankel2(m, k * r)
    wave = np.outer(np.exp(-2j * np.pi * frequency * times), profile)  # (N, R)
    comb = 22.1 + (np.arange(9) - 4) * 0.25 / times[-1]
    lock_in = np.exp(2j * np.pi * np.outer(comb, times)) * weights / weights.sum()
    spread = 5e-9 * np.sqrt(r[0] / r)
    rows = []
    for seed in range(150):
        rng = np.random.default_rng(seed)
        noise = spread * (rng.normal(size=wave.shape) + 1j * rng.normal(size=wave.shape))
        tone = refine_tone(comb, lock_in @ (wave + noise), times, weights)
        fit = fit_partial_wave(
            r, tone.profile, m, tone.frequency, k, phase_stderr=tone.phase_stderr
        )
        rows.append(_z_scores(fit, outgoing, incoming))
        rows[-1]["f"] = (tone.frequency - frequency) / tone.frequency_stderr
        rows[-1]["k"] = (fit.wavenumber - k) / fit.wavenumber_stderr
    _assert_honest(rows)


def test_a_tone_beyond_its_comb_is_refused_not_fitted_at_the_comb_end():
    """A tone at 19 Hz, lock-ins around 18.2 Hz (to 18.59 Hz): the fit stopped at the
    comb's end, 18.59 Hz, and took a quarter of the amplitude, silently."""
    times = np.arange(FRAMES) / FPS
    weights = np.sin(np.pi * times / times[-1]) ** 2
    comb = 18.2 + (np.arange(9) - 4) * 0.25 / times[-1]
    series = np.exp(-2j * np.pi * 19.0 * times)[:, np.newaxis] * np.ones(8)
    lock_ins = (np.exp(2j * np.pi * np.outer(comb, times)) * weights / weights.sum()) @ series
    with pytest.raises(InputError, match=r"rises to 18\.59 Hz.*the tone lies beyond"):
        refine_tone(comb, lock_ins, times, weights)


class _MapsInMemory:
    """Maps held in memory, with the attributes of a ``WaveMaps`` that the analysis reads."""

    def __init__(self, maps: np.ndarray, times: np.ndarray, pixel: float) -> None:
        self.path, self.label = Path("memory"), "fused"
        self.shape, self.pixel_size = maps.shape[1:], (pixel, pixel)
        self.clock, self.frames = frame_clock(times), times.size
        self.k_cut, self.k_cut_source, self.wider = math.pi / pixel, "the pixels", None
        self._maps = maps

    def blocks(self, size: int = 64):
        for start in range(0, self.frames, size):
            yield self.clock.times[start : start + size], self._maps[start : start + size]


def _two_tones(
    waves: tuple[PartialWave, PartialWave],
    *,
    modes: tuple[tuple[int, float], ...] = (),
    frames: int = FRAMES,
):
    """Two partial waves in 2 nm of noise, ``frames`` at 100 per s (256: a resolution of
    0.39 Hz, (m, f) bins of 0.78 Hz), through the whole analysis: the two strongest modes,
    or ``modes``."""
    surface = PartialWaves(waves, centre=CENTRE_MAP, core_radius=3e-3, depth=5e-3)
    times = np.arange(frames) / FPS
    maps = sample(surface, times, SIZE, PIXEL, noise=2e-9)
    options = WaveOptions(
        fluid=Fluid(),
        depth=5e-3,
        fit=False,
        segment=128,
        centre=CENTRE_MAP,
        r_range=(5e-3, 21e-3),
        m_max=4,
        n_modes=2,
        modes=modes,
    )
    return analyse_waves(_MapsInMemory(maps, times, PIXEL), options)  # type: ignore[arg-type]


def test_two_tones_e_omega_blends_are_each_fitted_around_their_own_peak(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """m = 1 at 18 Hz and m = -1 at 19 Hz, bins of 0.78 Hz: E(omega), which sums every m,
    shows one peak between them, the one candidate tone; the (m, f) spectrum tells them
    apart. The m = -1 mode was refined on the candidate's comb and stopped at its end:
    18.59 Hz, its outgoing amplitude 75 % low and 171 degrees off, with no note.

    Its own comb's lock-ins come from the ring samples kept in pass 2, or, past their
    budget, from one more pass over the maps: the same fits."""
    waves = (PartialWave(1, 18.0, 10e-9, 10e-9), PartialWave(-1, 19.0, 8e-9, 6e-9))
    results = _two_tones(waves)
    assert results.notes == []
    fits = {fit.m: fit for fit in results.partial_waves}
    assert set(fits) == {1, -1}
    for wave in waves:
        fit = fits[wave.m]
        assert fit.frequency == pytest.approx(wave.frequency, abs=0.01)
        for found, truth in ((fit.outgoing, wave.outgoing), (fit.incoming, wave.incoming)):
            assert abs(found) == pytest.approx(abs(truth), rel=0.03)
            assert abs(np.angle(found / truth)) < math.radians(3)
    monkeypatch.setattr(analysis, "KEPT_SAMPLES_BYTES", 0)
    again = _two_tones(waves)
    assert [fit.as_dict() for fit in again.partial_waves] == [
        fit.as_dict() for fit in results.partial_waves
    ]


def _same_m_pair(second: float, *, modes: tuple[tuple[int, float], ...] = ()):
    """m = 1 at 18 Hz (10, 10 nm) and at ``second`` (8, 6 nm) (:func:`_two_tones`)."""
    waves = (PartialWave(1, 18.0, 10e-9, 10e-9), PartialWave(1, second, 8e-9, 6e-9))
    return _two_tones(waves, modes=modes)


@pytest.mark.parametrize("second", [18.4, 18.8])
def test_two_tones_of_one_m_too_close_to_part_are_a_note_not_one_wrong_fit(second):
    """Two tones of m = 1, 0.4 and 0.8 Hz apart: E(omega) and the (m, f) spectrum show
    one, and its fit took both as one tone between them: 17.81 Hz and |out| 7.4 nm, 30
    standard errors off (0.4 Hz), 18.11 Hz and 10.8 nm (0.8 Hz), without a word. Now a
    note names the second tone, and no partial wave of m = 1 is reported."""
    results = _same_m_pair(second)
    assert all(fit.m != 1 for fit in results.partial_waves)
    (note,) = [note for note in results.notes if "not one steady tone" in note]
    found = float(note.split("a second tone near ")[1].split(" Hz")[0])
    assert found == pytest.approx(second, abs=0.1), note
    with pytest.raises(InputError, match=r"\(m, f\) = \(1, 18 Hz\): not one steady tone"):
        _same_m_pair(second, modes=((1, 18.0),))


def test_two_tones_of_one_m_that_a_long_record_parts_are_both_fitted():
    """m = 1 at 18 and 19.2 Hz in 20.5 s (2048 frames: 59 resolutions apart). The (m, f)
    spectrum's segments of 128 frames (0.78 Hz bins) blended them into one peak at
    18.3 Hz, whose fit failed, and a spurious m = -3 at 19.7 Hz: neither wave came out.
    Its segments now grow with the record (256 frames here): both are fitted."""
    results = _two_tones(
        (PartialWave(1, 18.0, 10e-9, 10e-9), PartialWave(1, 19.2, 8e-9, 6e-9)), frames=2048
    )
    assert results.notes == []
    assert results.mf is not None and results.mf.frequency[1] == pytest.approx(100 / 256)
    fits = sorted(results.partial_waves, key=lambda fit: fit.frequency)
    assert [fit.m for fit in fits] == [1, 1]
    for fit, (frequency, outgoing, incoming) in zip(
        fits, ((18.0, 10e-9, 10e-9), (19.2, 6e-9, 8e-9)), strict=True
    ):
        assert fit.frequency == pytest.approx(frequency, abs=0.01)
        assert abs(fit.outgoing) == pytest.approx(outgoing, rel=0.03)
        assert abs(fit.incoming) == pytest.approx(incoming, rel=0.03)


def test_a_mode_whose_peak_lies_off_its_tone_by_more_than_a_comb_is_found(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """In 20.5 s a comb spans +-0.05 Hz, less than an (m, f) peak's error in a field of
    many waves can be (0.015 Hz past a comb of 0.02 Hz in 80 s of ``bench_waves``').
    Peaks put 0.1 Hz off their tones: the comb around each peak missed its tone (a note,
    the tone beyond the comb); the search around the peak finds it."""
    strongest = MFSpectrum.strongest

    def off(self: MFSpectrum, count: int, *, f_min: float = 0.0) -> list[tuple[int, float]]:
        return [(m, f + 0.1) for m, f in strongest(self, count, f_min=f_min)]

    monkeypatch.setattr(MFSpectrum, "strongest", off)
    waves = (PartialWave(1, 18.0, 10e-9, 10e-9), PartialWave(-1, 25.0, 8e-9, 6e-9))
    results = _two_tones(waves, frames=2048)
    assert results.notes == []
    found = sorted((fit.m, fit.frequency) for fit in results.partial_waves)
    assert [m for m, _ in found] == [-1, 1]
    assert [f for _, f in found] == pytest.approx([25.0, 18.0], abs=0.005)


def test_a_tone_of_the_same_m_three_resolutions_away_leaves_the_fit_alone():
    """18 and 19.2 Hz at m = 1: the comb around 18 Hz sees the other's leakage (the
    residual stands out of the noise) but a second tone moves the profile by 0.3 %:
    18 Hz is fitted, within 1 %."""
    results = _same_m_pair(19.2)
    assert not any("not one steady tone" in note for note in results.notes), results.notes
    (fit,) = [fit for fit in results.partial_waves if fit.m == 1]
    assert fit.frequency == pytest.approx(18.0, abs=0.01)
    assert abs(fit.outgoing) == pytest.approx(10e-9, rel=0.01)


def _comb_lock_ins(
    seed: int, second: tuple[float, float] | None = None, *, common: float | None = None
):
    """Lock-ins of 60 rings at a comb around 18 Hz (2.56 s at 100 frames/s): a steady
    tone of about 3 nm a ring in white noise of 5 % of it a lock-in, ``second`` (Hz,
    relative amplitude), a second tone of the same profile, and ``common`` (Hz), a tone
    of 1 nm the same on every ring (as each frame's level is at m = 0)."""
    rng = np.random.default_rng(seed)
    t = np.arange(FRAMES) / FPS
    w = np.ones_like(t)
    comb = 18.0 + (np.arange(9) - 4) * 0.25 / np.ptp(t)
    rings = np.arange(60)
    profile = 3e-9 * (1 + 0.5 * np.cos(rings / 9)) * np.exp(1j * rings / 5)
    tones = [(18.0, 1.0)] + ([second] if second else [])
    series = sum(a * profile * np.exp(-2j * np.pi * f * t)[:, None] for f, a in tones)
    if common is not None:
        series = series + 1e-9 * np.exp(-2j * np.pi * common * t)[:, None]
    sigma = 0.05 * 3e-9 * math.sqrt(t.size)  # a lock-in's noise: 5 % of 3 nm in each part
    series = series + sigma * (
        rng.standard_normal(series.shape) + 1j * rng.standard_normal(series.shape)
    )
    lock_ins = (np.exp(2j * np.pi * np.outer(comb, t)) * w) @ series / np.sum(w)
    return comb, lock_ins, t, w, (0.05 * 3e-9) ** 2


@pytest.mark.parametrize("seed", range(4))
def test_a_steady_tone_beside_noise_measured_low_is_fitted_and_a_second_tone_named(seed):
    """The noise beside a tone can be measured low by a factor of 2: m = 0 holds each
    frame's piston, which is not white. ``accuracy_waves.py``'s seed 8: its steady m = 0
    wave at 14 Hz (the two halves of the record gave amplitudes 0.4 % apart) left 2.01
    times that noise, and a second tone moved its profile by 2.25 %: a note, the wave
    not fitted. Here the noise is given 2.5 times too low: a steady tone leaves 2.2-2.4
    times it (a note before, with a profile moved by 3 %) and is one tone; a second tone
    of 30 % at 18.4 Hz leaves 12 times it and is still named."""
    comb, lock_ins, t, w, s2 = _comb_lock_ins(seed)
    noise = np.full(lock_ins.shape[1], s2 / 2.5)
    tone = refine_tone(comb, lock_ins, t, w)
    assert unsteady_tone(comb, lock_ins, t, w, tone=tone, noise=noise) is None
    comb, lock_ins, t, w, s2 = _comb_lock_ins(seed, second=(18.4, 0.3))
    tone = refine_tone(comb, lock_ins, t, w)
    found = unsteady_tone(comb, lock_ins, t, w, tone=tone, noise=noise)
    assert found is not None and found.second == pytest.approx(18.4, abs=0.1)


@pytest.mark.parametrize("seed", range(2))
def test_m0_lock_ins_leave_each_frames_level_out_of_the_steadiness_test(seed):
    """At m = 0 each frame's level (the maps' piston, the same on every ring) is in the
    lock-ins, and it is not white: in ``accuracy_waves.py``'s seed 10 the steady m = 0
    wave at 14 Hz left 5.2 times the noise beside it, all of it common to every ring,
    and came out as a note. A piston's tone of 1 nm 0.3 Hz from a steady tone of 3 nm:
    taken for a second tone at any other m, left out at m = 0; a second tone that
    varies over the rings is named at m = 0 too."""
    comb, lock_ins, t, w, s2 = _comb_lock_ins(seed, common=17.7)
    noise = np.full(lock_ins.shape[1], s2)
    tone = refine_tone(comb, lock_ins, t, w)
    assert unsteady_tone(comb, lock_ins, t, w, tone=tone, noise=noise) is not None
    assert unsteady_tone(comb, lock_ins, t, w, tone=tone, noise=noise, level=True) is None
    comb, lock_ins, t, w, s2 = _comb_lock_ins(seed, second=(18.4, 0.3), common=17.7)
    tone = refine_tone(comb, lock_ins, t, w)
    found = unsteady_tone(comb, lock_ins, t, w, tone=tone, noise=noise, level=True)
    assert found is not None and found.second == pytest.approx(18.4, abs=0.1)
