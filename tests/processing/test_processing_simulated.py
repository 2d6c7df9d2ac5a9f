"""Accuracy on frames of the optics simulator (holoview.optics): the shot-noise floor, fusion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from wavy_scene import LABELS, true_peaks

from holoview.optics.families import coherent_displacement, predict_families
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.optics.wave_fields import DampedMode
from holoview.processing.fourier.resample import box_positions
from holoview.processing.maps.coregister import DisplacementEstimator
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.maps.heights import fuse
from holoview.processing.maps.map_moves import coregister
from holoview.processing.peaks.detection import Peak, find_peaks

SIGMA = 40.0  # bump width, pixels
HEIGHT = 5e-9  # bump height, m


def labelled_peaks(
    setup: Setup, frame: np.ndarray
) -> tuple[list[Peak], dict[str, tuple[float, float]]]:
    """Found peaks named after the predicted families (twin flipped to the family's), and
    each family's displacement in frame pixels ``(rows, cols)``."""
    rows, cols = setup.shape
    found = find_peaks(frame)
    peaks, shifts = [], {}
    for family in predict_families(setup, max_order=2, second_order=False):
        fx, fy = family.observed_carrier
        for peak in found:
            for candidate in (peak, peak.flipped()):
                cx, cy = candidate.carrier
                if (
                    np.hypot((cx - fx) * cols, (cy - fy) * rows) < 1.0
                    and family.label not in shifts
                ):
                    if any(
                        p.carrier == candidate.carrier or p.carrier == peak.flipped().carrier
                        for p in peaks
                    ):
                        continue
                    peaks.append(candidate.relabelled(family.label, family.alpha))
                    dx, dy = family.displacement
                    shifts[family.label] = (dy / setup.pixel_pitch, dx / setup.pixel_pitch)
    return peaks, shifts


def bump(shape: tuple[int, int], y: np.ndarray, x: np.ndarray) -> np.ndarray:
    rows, cols = shape
    return HEIGHT * np.exp(-((y - rows / 2) ** 2 + (x - cols / 2) ** 2) / (2 * SIGMA**2))


def test_rb1_reaches_the_shot_noise_bound_and_fusion_beats_it() -> None:
    setup = Setup(shape=(256, 256))
    synthesizer = HologramSynthesizer(setup, noise="poisson")
    rng = np.random.default_rng(50)
    rows, cols = setup.shape
    yy, xx = np.mgrid[:rows, :cols].astype(float)
    surface = bump(setup.shape, yy, xx)
    first = synthesizer.render(0.0, rng=rng)
    peaks, shifts = labelled_peaks(setup, first)
    labels = [p.label for p in peaks]
    assert {"RB1", "RF", "FB1", "RB2"} <= set(labels), labels
    demod = Demodulator(setup.shape, peaks, reference="relative", wavelength=setup.wavelength)
    demod.process(first)
    by, bx = box_positions(demod.box_shape, setup.shape)
    scale = (demod.box_shape[0] / rows, demod.box_shape[1] / cols)
    inner = (slice(2, -2), slice(2, -2))
    errors: dict[str, list[float]] = {label: [] for label in labels}
    fused_errors: list[float] = []
    bounds: dict[str, float] = {}
    for k in range(6):
        sign = 1 if k % 2 == 0 else -1
        result = demod.process(synthesizer.render(surface if k % 2 == 0 else 0.0, rng=rng))
        maps, noises, masks = [], [], []
        for i, r in enumerate(result.peaks):
            dy, dx = shifts[r.peak.label]
            truth = sign * bump(setup.shape, by[:, None] + dy, bx[None, :] + dx)
            errors[r.peak.label].append(float(np.mean((r.delta_h - truth)[inner] ** 2)))
            amplitude = float(np.median(np.abs(r.field)[inner])) / result.mean_counts
            phase_bound = (
                np.sqrt(2 * demod.area_fraction(i) / (2 * setup.photons_per_pixel)) / amplitude
            )
            bounds[r.peak.label] = phase_bound * setup.wavelength / (4 * np.pi * r.peak.alpha)
            # co-register on RB1's grid with the model's displacement
            back = (
                dy * scale[0] - shifts["RB1"][0] * scale[0],
                dx * scale[1] - shifts["RB1"][1] * scale[1],
            )
            (moved,) = coregister([r.delta_h], [(-back[0], -back[1])])
            maps.append(moved)
            noises.append(r.noise_height)
            masks.append(r.mask & np.isfinite(moved))
        fused, _ = fuse(maps, noises, masks=masks)
        dy, dx = shifts["RB1"]
        truth = sign * bump(setup.shape, by[:, None] + dy, bx[None, :] + dx)
        fused_errors.append(float(np.mean((fused - truth)[inner] ** 2)))
    rms = {label: float(np.sqrt(np.mean(v))) for label, v in errors.items()}
    assert rms["RB1"] <= 1.2 * bounds["RB1"]
    assert rms["RB1"] == pytest.approx(bounds["RB1"], rel=0.2)
    assert np.sqrt(np.mean(fused_errors)) < min(rms.values())


def test_measured_displacements_match_the_model_and_coregistered_fusion_wins() -> None:
    """Over 40 frames of moving waves the maps' shifts are measured; RF and RB2 agree
    with the model's displacements. FB1 shares its carrier and alpha with B2B1, and the
    two nearly cancel: its map's shift is far from either family's, and only a measured
    shift co-registers it. Fused without co-registration is worse than RB1 alone."""
    setup = Setup(shape=(256, 256), depth=0.02)
    synthesizer = HologramSynthesizer(setup, noise="poisson")
    rng = np.random.default_rng(5)

    def waves(t: int, y: np.ndarray, x: np.ndarray) -> np.ndarray:
        total = np.zeros(np.broadcast(y, x).shape)
        for k in range(5):
            ky, kx = np.random.default_rng(k).uniform(-0.03, 0.03, 2)
            total += 10e-9 * np.cos(2 * np.pi * (ky * y + kx * x) - 0.9 * t + k)
        return total

    yy, xx = np.mgrid[:256, :256].astype(float)
    first = synthesizer.render(waves(0, yy, xx), rng=rng)
    peaks, shifts = labelled_peaks(setup, first)
    peaks.sort(key=lambda p: p.label != "RB1")  # RB1's grid is the reference
    demod = Demodulator(setup.shape, peaks, reference="relative", wavelength=setup.wavelength)
    demod.process(first)
    estimator = DisplacementEstimator(demod.box_shape, len(peaks))
    frames = []
    for t in range(1, 41):
        result = demod.process(synthesizer.render(waves(t, yy, xx), rng=rng))
        maps = [np.where(r.mask, r.delta_h, np.nan) for r in result.peaks]
        estimator.add(maps)
        frames.append((t, maps, [r.noise_height for r in result.peaks]))
    found = {p.label: d for p, d in zip(peaks, estimator.displacements(), strict=True)}
    scale = demod.box_shape[0] / setup.shape[0]
    for label in ("RF", "RB2"):
        expected = [(shifts["RB1"][k] - shifts[label][k]) * scale for k in (0, 1)]
        assert found[label].measured
        assert found[label].shift == pytest.approx(expected, abs=0.03), label
    fb1 = [(shifts["RB1"][k] - shifts["FB1"][k]) * scale for k in (0, 1)]
    assert found["FB1"].measured and math.dist(found["FB1"].shift, fb1) > 0.5

    by, bx = box_positions(demod.box_shape, setup.shape)
    dy, dx = shifts["RB1"]
    inner = (slice(2, -2), slice(2, -2))
    measured = [found[p.label].shift for p in peaks]
    squared: dict[str, list[float]] = {"RB1": [], "raw": [], "coregistered": []}
    for t, maps, noises in frames:
        truth = waves(t, by[:, None] + dy, bx[None, :] + dx)
        truth -= waves(t - 1, by[:, None] + dy, bx[None, :] + dx)
        moved = coregister(maps, measured)
        for name, use in (("raw", maps), ("coregistered", moved)):
            fused, _ = fuse(use, noises, masks=[np.isfinite(m) for m in use])
            squared[name].append(float(np.nanmean((fused - truth)[inner] ** 2)))
        squared["RB1"].append(float(np.nanmean((maps[0] - truth)[inner] ** 2)))
    rms = {name: math.sqrt(np.mean(v)) for name, v in squared.items()}
    assert rms["coregistered"] < rms["RB1"] < rms["raw"], rms


def test_a_ringing_mode_with_no_shift_between_the_peaks_gives_none() -> None:
    """A damped m = 2 mode about a wavelength across the maps (the ringdown simulation):
    the truth puts the peaks' maps within 0.02 map pixel of each other. The window's
    pull made each residual mostly noise, and every one was added to the estimate: RB2
    walked 0.32 map pixel away, FB1 0.21 and FB2 0.25 in 50 frames; the run of the
    issue, RF a camera pixel in each axis."""
    setup = Setup(
        shape=(256, 256),
        pixel_pitch=160e-6,
        depth=3e-3,
        m_r=(0.4e-3, 0.025e-3),
        m_b=(0.025e-3, 0.3e-3),
        mirror_reflectivity=0.1,
    )
    mode = DampedMode(2, 12.0, 0.8, 60e-9, centre=(3e-3, -2e-3), depth=3e-3)
    labels = LABELS
    peaks = true_peaks(setup, labels)
    synthesizer = HologramSynthesizer(setup, noise="poisson")
    rng = np.random.default_rng(1)
    x, y = pixel_coordinates(setup)
    demod = Demodulator(
        setup.shape, peaks, reference="absolute", wavelength=setup.wavelength, radius="bound"
    )
    demod.process(synthesizer.render(np.zeros(setup.shape), rng=rng))
    estimator = DisplacementEstimator(demod.box_shape, len(peaks))
    for i in range(1, 51):
        height = mode(0.002 + i / 50.0, x, y)
        result = demod.process(synthesizer.render(height, rng=rng))
        estimator.add([np.where(r.mask, r.delta_h, np.nan) for r in result.peaks])
    scale = demod.box_shape[0] / setup.shape[0]
    rb1 = coherent_displacement(setup, "RB1")
    for label, found in zip(labels, estimator.displacements(), strict=True):
        dx, dy = np.subtract(rb1, coherent_displacement(setup, label)) / setup.pixel_pitch
        assert abs(dy * scale) < 0.02 and abs(dx * scale) < 0.02  # no shift in truth
        assert found.shift == pytest.approx((dy * scale, dx * scale), abs=0.1), label
