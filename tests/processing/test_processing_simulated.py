"""Accuracy on frames of the optics simulator (holoview.optics): the shot-noise floor, fusion."""

from __future__ import annotations

import numpy as np
import pytest

from holoview.optics.families import predict_families
from holoview.optics.setup import Setup
from holoview.optics.synthesis import HologramSynthesizer
from holoview.processing.demodulate import Demodulator
from holoview.processing.heights import fuse, shift_map
from holoview.processing.peaks import Peak, find_peaks
from holoview.processing.resample import box_positions

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
            maps.append(shift_map(r.delta_h, back))
            noises.append(r.noise_height)
            masks.append(r.mask)
        fused, _ = fuse(maps, noises, masks=masks)
        dy, dx = shifts["RB1"]
        truth = sign * bump(setup.shape, by[:, None] + dy, bx[None, :] + dx)
        fused_errors.append(float(np.mean((fused - truth)[inner] ** 2)))
    rms = {label: float(np.sqrt(np.mean(v))) for label, v in errors.items()}
    assert rms["RB1"] <= 1.2 * bounds["RB1"]
    assert rms["RB1"] == pytest.approx(bounds["RB1"], rel=0.2)
    assert np.sqrt(np.mean(fused_errors)) < min(rms.values())
