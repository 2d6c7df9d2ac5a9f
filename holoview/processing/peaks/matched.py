"""A window matched to the surface: per peak, the radius that minimises the expected map error.

The demodulated field of a peak is the spectrum around its carrier times the window
``W``: a bin of surface power ``P_s`` (its sideband content) costs ``(1 - W)^2 P_s`` of
map error when the window cuts it, and a bin of noise power ``N`` costs ``W^2 N`` when
the window passes it (Parseval; the phase is linear in the field for small
modulations). :func:`matched_window` measures both from one frame's spectrum
(:func:`measure_spectrum`) and takes, between :data:`MIN_RADIUS_BINS` FFT bins and the
bound (half the distance to the nearest other term:
:func:`~holoview.processing.fourier.windows.auto_radii`), the radius of least
``sum (1 - W)^2 (P - N) + W^2 N`` over the bins within the bound. A bin whose surface
power stands above the noise is therefore passed: the window never cuts a wave field
that the spectrum shows above its noise floor.

The spectrum is taken through a 4-term Blackman-Harris apodisation (sidelobes 92 dB
down, main lobe :data:`LOBE_BINS` bins wide): the carrier's own leakage stays inside its
main lobe instead of spreading as a cross along the axes (a plain FFT's edge
discontinuity), so what remains around the carrier is the surface's content. Both the
surface power and the noise are scaled alike by the apodisation: their ratio is the
frame's.

Without measurable surface power around a carrier (a flat surface: the excess power
outside the main lobe within :data:`MEASURABLE_SIGMAS` standard errors of zero), the
radius is the bound, with a note: nothing says how narrow the surface's spectrum is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from holoview.errors import InputError
from holoview.processing.fourier.fftplans import DEFAULT_THREADS, rfft2_plan
from holoview.processing.fourier.frames import check_frame
from holoview.processing.fourier.windows import radial_window

__all__ = [
    "LOBE_BINS",
    "MEASURABLE_SIGMAS",
    "SurfaceSpectrum",
    "Window",
    "matched_window",
    "measure_spectrum",
]

#: Half width (FFT bins) of the apodisation's main lobe: a carrier's own power.
LOBE_BINS = 4.0

#: Surface power counts as measured when the excess over the noise outside the carrier's
#: main lobe is this many standard errors of the noise above zero.
MEASURABLE_SIGMAS = 5.0

#: Step (FFT bins) of the radii tried and of the radial profile.
STEP_BINS = 0.25

#: Smallest matched radius, FFT bins (as the automatic radii's floor).
MIN_RADIUS_BINS = 4.0

#: Coefficients of the 4-term Blackman-Harris window.
_BLACKMAN_HARRIS = (0.35875, 0.48829, 0.14128, 0.01168)

#: The rules a window radius is chosen by.
RULES = ("matched", "bound", "given")


@dataclass(frozen=True)
class Window:
    """One peak's window: its radius, shape and why.

    Attributes
    ----------
    radius : float
        Radius, cycles/pixel.
    kind : str
        Shape (:data:`~holoview.processing.fourier.windows.WINDOW_KINDS`).
    taper : float
        Edge width of a Tukey window, fraction of the radius.
    rule : {"matched", "bound", "given"}
        Matched to the surface's spectrum, the bound (widest reaching no other term),
        or given by the user.
    bound : float
        Half the distance to the nearest other term, cycles/pixel.
    reason : str
        One line saying why this radius.
    content : float or None
        Matched: how far from the carrier the surface's power stands above the noise
        floor (cycles/pixel, in whole annuli); else None.
    """

    radius: float
    kind: str
    taper: float
    rule: str
    bound: float
    reason: str
    content: float | None = None

    def to_dict(self) -> dict[str, object]:
        """The window as JSON-ready values (``radius_cpp``, ``kind``, ``taper``, ...)."""
        return {
            "radius_cpp": self.radius,
            "kind": self.kind,
            "taper": self.taper,
            "rule": self.rule,
            "bound_cpp": self.bound,
            "content_cpp": self.content,
            "reason": self.reason,
        }


def _apodisation(n: int) -> np.ndarray:
    phase = 2 * np.pi * np.arange(n) / n
    a0, a1, a2, a3 = _BLACKMAN_HARRIS
    return (a0 - a1 * np.cos(phase) + a2 * np.cos(2 * phase) - a3 * np.cos(3 * phase)).astype(
        np.float32
    )


@dataclass(frozen=True)
class SurfaceSpectrum:
    """One frame's apodised power spectrum and noise floor, what windows are matched to.

    Attributes
    ----------
    shape : tuple of int
        Frame shape ``(rows, cols)``.
    power : ndarray of float32, shape (rows, cols // 2 + 1)
        ``|S|^2`` of the apodised frame, half spectrum (``rfft2`` layout), counts^2.
    floor : float
        Noise power per bin, counts^2 (the median over the spectrum over ln 2: noise
        power is exponentially distributed, and peaks cover a few percent of it).
    """

    shape: tuple[int, int]
    power: np.ndarray
    floor: float

    def around(self, carrier: tuple[float, float], radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Distances (cycles/pixel) and powers of the bins within ``radius`` of ``carrier``.

        The full spectrum's bins, periodic; those of the other half are read from the
        twin (a real frame's spectrum is Hermitian).
        """
        rows, cols = self.shape
        fx, fy = float(carrier[0]), float(carrier[1])
        kx = np.arange(int(np.floor((fx - radius) * cols)), int(np.ceil((fx + radius) * cols)) + 1)
        ky = np.arange(int(np.floor((fy - radius) * rows)), int(np.ceil((fy + radius) * rows)) + 1)
        rho = np.hypot(kx[None, :] / cols - fx, ky[:, None] / rows - fy)
        inside = rho <= radius
        yy, xx = np.broadcast_arrays(ky[:, None] % rows, kx[None, :] % cols)
        mirrored = xx > cols // 2
        yy = np.where(mirrored, (-yy) % rows, yy)
        xx = np.where(mirrored, cols - xx, xx)
        return rho[inside], self.power[yy[inside], xx[inside]].astype(np.float64)


def measure_spectrum(frame: np.ndarray, *, threads: int | None = None) -> SurfaceSpectrum:
    """Return the apodised power spectrum and noise floor of one frame (module documentation).

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        A hologram (counts); not modified.
    threads : int, optional
        FFTW threads.
    """
    array = check_frame(frame)
    rows, cols = array.shape
    plan = rfft2_plan(array.shape, threads=threads or DEFAULT_THREADS)
    buffer = plan.input_array
    mean = float(np.mean(array, dtype=np.float64))
    np.subtract(array, np.float32(mean), out=buffer, casting="unsafe")
    buffer *= np.outer(_apodisation(rows), _apodisation(cols))
    plan()
    half = plan.output_array
    power = (half.real * half.real + half.imag * half.imag).astype(np.float32)
    floor = float(np.median(power[::2, 1::2])) / np.log(2)
    if not (np.isfinite(floor) and floor > 0):
        raise InputError("the frame's spectrum has no noise floor (a constant or non-finite frame)")
    return SurfaceSpectrum((rows, cols), power, floor)


def matched_window(
    spectrum: SurfaceSpectrum,
    carrier: tuple[float, float],
    bound: float,
    *,
    kind: str,
    taper: float,
) -> Window:
    """Return the window of least expected map error around ``carrier``, at most ``bound``.

    Parameters
    ----------
    spectrum : SurfaceSpectrum
        The frame's apodised power spectrum (:func:`measure_spectrum`).
    carrier : tuple of float
        ``(fx, fy)``, cycles/pixel.
    bound : float
        The widest radius reaching no other term, cycles/pixel.
    kind, taper
        The window's shape (:func:`~holoview.processing.fourier.windows.radial_window`).

    Returns
    -------
    Window
        Rule ``"matched"``; the bound (rule ``"bound"``, with the reason) where the
        spectrum shows no measurable surface power around the carrier.
    """
    rows, cols = spectrum.shape
    per_bin = 1.0 / max(rows, cols)  # cycles/pixel of one bin along the finer axis
    smallest = MIN_RADIUS_BINS / min(rows, cols)
    if bound <= smallest:
        return Window(bound, kind, taper, "bound", bound, "the bound is the smallest window")
    rho, power = spectrum.around(carrier, bound)
    noise = spectrum.floor
    excess = power - noise
    lobe = rho > LOBE_BINS * per_bin
    outside = int(np.count_nonzero(lobe))
    measured = float(excess[lobe].sum())
    if outside == 0 or measured <= MEASURABLE_SIGMAS * noise * np.sqrt(outside):
        return Window(
            bound,
            kind,
            taper,
            "bound",
            bound,
            "no measurable surface power around the carrier: the bound",
        )
    step = STEP_BINS * per_bin
    edges = np.arange(0.0, bound + step, step)
    which = np.minimum(np.searchsorted(edges, rho, side="right") - 1, len(edges) - 2)
    signal = np.bincount(which, weights=excess, minlength=len(edges) - 1)
    count = np.bincount(which, minlength=len(edges) - 1).astype(np.float64)
    centres = edges[:-1] + step / 2
    radii = np.arange(smallest, bound, step)
    radii = np.append(radii, bound)
    w = np.stack([radial_window(kind, centres, r, taper=taper) for r in radii])
    error = ((1.0 - w) ** 2 * signal + w**2 * count * noise).sum(axis=1)
    best = int(np.argmin(error))
    above = np.flatnonzero(signal > count * noise)
    content = float(edges[above[-1] + 1]) if above.size else 0.0
    radius = float(radii[best])
    reason = (
        f"matched: the surface's power stands above the noise out to {content:.4f} "
        f"cycles/pixel; the bound is {bound:.4f}"
    )
    return Window(radius, kind, taper, "matched", bound, reason, content)
