"""A wavy surface on the optics simulator: travelling capillary-gravity waves, and their truth.

The case of issue 23: a 512 x 512 camera at 40 um object-side pitch, 400 frames/s,
water 3 mm deep, five travelling waves of wavenumbers 600-2500 rad/m (0.004 to 0.016
cycles/pixel) and 20 nm rms, over a bench whose first-order lattice is spaced about 0.1
cycles/pixel (RB1, RF, FB1, RB2, RB3, FB2 demodulated). The strongest waves' sidebands
around RB1 (relative amplitude ``2 pi alpha h_q / wavelength``) are several times
brighter than RB3's and FB2's peaks. 4000 photons per pixel: at 800 FB2's map (amplitude
0.0013, alpha 2.67) is noise-limited below a correlation of 0.97 at any radius.

The benchmark ``benchmarks/bench_wavy.py`` imports this module too (from this folder).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from holoview.optics.families import coherent_amplitude, coherent_displacement, predict_families
from holoview.optics.setup import Setup
from holoview.optics.surfaces import dispersion_omega
from holoview.optics.synthesis import HologramSynthesizer, pixel_coordinates
from holoview.processing.peaks.detection import Peak

LABELS = ("RB1", "RF", "FB1", "RB2", "RB3", "FB2")
PITCH_M = 40e-6
FPS = 400.0
DEPTH_M = 3e-3


def wavy_setup(size: int = 512, *, reflectivity: float = 0.6, photons: float = 4000.0) -> Setup:
    """The bench: RF at (0.150, 0.090), FB1 at (-0.070, 0.070) cycles/pixel.

    With the submerged mirror's reflectivity 0.6 the weakest family (FB2) has an
    amplitude of 0.003 and RB3 0.006, against 0.01 for the strongest waves' sidebands
    around RB1; the camera's full well is four times the mean.
    """
    return Setup(
        shape=(size, size),
        pixel_pitch=PITCH_M,
        depth=DEPTH_M,
        m_r=(1.0e-3, 0.6e-3),
        m_b=(-3.5e-4, 3.5e-4),
        mirror_reflectivity=reflectivity,
        photons_per_pixel=photons,
        saturation=4 * photons,
    )


@dataclass(frozen=True)
class TravellingWaves:
    """``h(t, x, y) = sum_i a_i cos(k_i (x cos theta_i + y sin theta_i) - omega_i t + phi_i)``.

    ``omega_i`` from the capillary-gravity dispersion on the bench's depth; SI units
    (t in s, x and y in m on the object plane, h in m).
    """

    k: np.ndarray  # rad/m
    theta: np.ndarray  # rad
    amplitude: np.ndarray  # m
    phase: np.ndarray  # rad
    omega: np.ndarray  # rad/s

    is_uniform = False

    def __call__(self, t: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Height, m, broadcast over ``x`` and ``y``."""
        total = np.zeros(np.broadcast_shapes(np.shape(x), np.shape(y)))
        for i in range(len(self.k)):
            along = np.cos(self.theta[i]) * x + np.sin(self.theta[i]) * y
            total += self.amplitude[i] * np.cos(
                self.k[i] * along - self.omega[i] * t + self.phase[i]
            )
        return total

    def mean_level(self, t: float) -> float:
        """Zero: waves conserve volume, m."""
        return 0.0

    @property
    def q(self) -> np.ndarray:
        """Each wave's wave vector on the camera, ``(fx, fy)`` cycles/pixel, shape (n, 2)."""
        scale = self.k * PITCH_M / (2 * np.pi)
        return np.stack([scale * np.cos(self.theta), scale * np.sin(self.theta)], axis=1)


def travelling_waves(
    seed: int,
    *,
    count: int = 5,
    k_range: tuple[float, float] = (600.0, 2500.0),
    rms: float = 20e-9,
    shape: tuple[int, int] = (512, 512),
) -> TravellingWaves:
    """Waves of random direction and wavenumber (log-uniform in ``k_range``, rad/m).

    Amplitudes Rayleigh-distributed times ``k_min / k`` (a steep spectrum), scaled to a
    spatial rms ``rms`` (m) over the frame at t = 0.
    """
    rng = np.random.default_rng(seed)
    k = np.exp(rng.uniform(np.log(k_range[0]), np.log(k_range[1]), count))
    theta = rng.uniform(0, 2 * np.pi, count)
    amplitude = rng.rayleigh(1.0, count) * (k_range[0] / k)
    phase = rng.uniform(0, 2 * np.pi, count)
    omega = np.asarray(dispersion_omega(k, DEPTH_M), dtype=np.float64)
    waves = TravellingWaves(k, theta, amplitude, phase, omega)
    setup = Setup(shape=shape, pixel_pitch=PITCH_M)
    x, y = pixel_coordinates(setup)
    scale = rms / float(np.std(waves(0.0, x, y)))
    return TravellingWaves(k, theta, amplitude * scale, phase, omega)


def true_peaks(setup: Setup, labels: tuple[str, ...] = LABELS) -> list[Peak]:
    """The families' true carriers, amplitudes and alphas, labelled."""
    families = {f.label: f for f in predict_families(setup, max_order=3, second_order=False)}
    return [
        Peak(
            families[n].observed_carrier,
            coherent_amplitude(setup, n) / 2,
            100.0,
            label=n,
            alpha=families[n].alpha,
        )
        for n in labels
    ]


def shifts_px(setup: Setup, labels: tuple[str, ...] = LABELS) -> dict[str, tuple[float, float]]:
    """Each family's displacement ``(dy, dx)``, frame pixels (where its map images h)."""
    out = {}
    for n in labels:
        dx, dy = coherent_displacement(setup, n)
        out[n] = (dy / setup.pixel_pitch, dx / setup.pixel_pitch)
    return out


def render(
    setup: Setup, waves: TravellingWaves, frames: int, seed: int = 0
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """``frames`` camera frames at :data:`FPS` (Poisson noise) and the true heights, m."""
    synthesizer = HologramSynthesizer(setup, noise="poisson")
    rng = np.random.default_rng(seed)
    x, y = pixel_coordinates(setup)
    images, heights = [], []
    for t in range(frames):
        h = waves(t / FPS, x, y)
        heights.append(h)
        images.append(synthesizer.render(h, rng=rng))
    return images, heights
