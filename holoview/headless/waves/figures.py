"""The figures of ``holoview waves``, drawn with matplotlib (Agg, no pyplot state).

Each function draws one PNG from :class:`~holoview.headless.waves.analysis.WaveResults`, axes in
physical units (k in rad/m, f in Hz, r in mm, heights in nm), for a talk:

- ``omega_k.png``: the power against f and |k| (all directions), and along the flow
  (signed: negative k travels against it), the fitted dispersion relation over both,
  the window's cut-off marked;
- ``energy.png``: E(k) and E(f);
- ``m_f.png``: the (m, f) spectrum, the fitted partial waves marked;
- ``partial_waves.png``: |A_m(r)| of each fitted partial wave with its Hankel fit and
  its incoming and outgoing parts;
- ``ringdown.png``: the band's series and the damped-mode fit, band-passed as the series;
- ``lockin.png``: amplitude and phase at the drive frequency, amplitudes of its harmonics,
  the centre marked.
"""

from __future__ import annotations

import math
import multiprocessing
from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter
from scipy import special

from holoview.headless.results.figures import map_edges
from holoview.headless.waves.analysis import WaveResults
from holoview.processing.waves.fit_text import with_error

__all__ = ["FIGURES", "draw_figures"]

#: Resolution of the figures, dots per inch.
DPI = 110

#: A figure's drawing function.
Drawer = Callable[[WaveResults, Path], None]

#: Figure file names, in the order they are drawn.
FIGURES = (
    "omega_k.png",
    "energy.png",
    "m_f.png",
    "partial_waves.png",
    "ringdown.png",
    "lockin.png",
)


def _save(figure: Figure, path: Path) -> None:
    FigureCanvasAgg(figure)
    figure.savefig(path, dpi=DPI, format="png")


def _log_norm(values: np.ndarray) -> LogNorm:
    positive = values[np.isfinite(values) & (values > 0)]
    if positive.size == 0:
        return LogNorm(1e-30, 1.0)
    top = float(np.percentile(positive, 99.9))
    return LogNorm(vmin=top * 1e-5, vmax=top)


def _fit_text(results: WaveResults) -> str:
    fit = results.dispersion
    if fit is None:
        return "no dispersion fit"
    held = set(fit.held)

    def value(name: str, v: float, e: float, scale: float, unit: str) -> str:
        if name in held:
            return f"{v * scale:.4g} {unit} (held)"
        return f"{v * scale:.4g} ± {e * scale:.2g} {unit}"

    return (
        f"σ = {value('sigma', fit.surface_tension, fit.surface_tension_stderr, 1e3, 'mN/m')}, "
        f"d = {value('depth', fit.depth, fit.depth_stderr, 1e3, 'mm')}, U = ("
        f"{fit.flow[0] * 1e3:.3g} ± {fit.flow_stderr[0] * 1e3:.2g}, "
        f"{fit.flow[1] * 1e3:.3g} ± {fit.flow_stderr[1] * 1e3:.2g}) mm/s"
    )


def _extent(k: np.ndarray, energy: np.ndarray, k_cut: float) -> float:
    """1.2 times the largest k (rad/m) where E(k) tops 1e-3 of its peak (at most k_cut)."""
    above = np.flatnonzero(energy >= 1e-3 * np.max(energy))
    if above.size == 0:
        return k_cut
    return float(min(k_cut, 1.2 * k[above[-1]]))


def omega_k_figure(results: WaveResults, path: Path) -> None:
    """``omega_k.png`` (module docstring)."""
    spectrum = results.spectrum
    fit = results.dispersion
    k, radial = spectrum.radial()
    cmap = colormaps["magma"].with_extremes(bad="black")
    figure = Figure(figsize=(12, 5))
    left, right = figure.subplots(1, 2)
    image = left.pcolormesh(
        k, spectrum.frequency, radial, norm=_log_norm(radial), shading="nearest", cmap=cmap
    )
    left.set_xlabel("wavenumber |k| (rad/m)")
    left.set_ylabel("frequency f (Hz)")
    left.set_title("power, all directions")
    angle = 0.0
    if fit is not None:
        speed = math.hypot(*fit.flow)
        angle = math.atan2(fit.flow[1], fit.flow[0]) if speed > 0 else 0.0
        curve_k = np.linspace(0.0, spectrum.k_cut, 400)
        for sign, style, name in ((1.0, "-", "with the flow"), (-1.0, "--", "against it")):
            omega = fit.omega(sign * curve_k * math.cos(angle), sign * curve_k * math.sin(angle))
            left.plot(curve_k, omega / (2 * math.pi), style, color="cyan", lw=1.0, label=name)
        left.legend(loc="upper right", fontsize=8, title="fitted dispersion", title_fontsize=8)
    left.axvline(spectrum.k_cut, color="white", lw=1.0, ls=":")
    left.text(
        spectrum.k_cut,
        0.5 * spectrum.frequency[-1],
        "window cut-off ",
        color="white",
        rotation=90,
        ha="right",
        va="center",
        fontsize=8,
    )
    left.set_xlim(0, spectrum.k_cut * 1.02)
    q, along = spectrum.along(angle)
    right.pcolormesh(
        q, spectrum.frequency, along, norm=_log_norm(along), shading="nearest", cmap=cmap
    )
    flowing = fit is not None and any(fit.flow)
    right.set_xlabel(
        f"wavenumber along {math.degrees(angle):.0f}° (rad/m; < 0: against the flow)"
        if flowing
        else "wavenumber along x (rad/m; < 0: travelling towards -x)"
    )
    right.set_title("power along the flow (zoom)" if flowing else "power along x (zoom)")
    reach = _extent(*spectrum.energy_k(), spectrum.k_cut)
    if fit is not None:
        curve = np.linspace(-reach, reach, 800)
        omega = fit.omega(curve * math.cos(angle), curve * math.sin(angle))
        right.plot(curve, omega / (2 * math.pi), color="cyan", lw=1.0, label="fitted dispersion")
        right.legend(loc="upper left", fontsize=8)
    right.set_xlim(-reach, reach)
    for axes in (left, right):
        axes.set_ylim(0, spectrum.frequency[-1])
    colourbar = figure.colorbar(image, ax=[left, right], fraction=0.03)
    colourbar.set_label("power density (m² Hz⁻¹ (rad/m)⁻²)")
    figure.suptitle(
        f"{results.maps.label}: {spectrum.segments} segments of "
        f"{spectrum.frequency.size * 2 - 2} frames; "
        f"{_fit_text(results)}",
        fontsize=9,
    )
    _save(figure, path)


def energy_figure(results: WaveResults, path: Path) -> None:
    """``energy.png`` (module docstring)."""
    spectrum = results.spectrum
    k, e_k = spectrum.energy_k()
    omega, e_omega = spectrum.energy_omega()
    figure = Figure(figsize=(11, 4.5))
    left, right = figure.subplots(1, 2)
    keep = (k > 0) & (e_k > 0)
    left.loglog(k[keep], e_k[keep], color="C0")
    left.axvline(spectrum.k_cut, color="grey", ls=":", label="window cut-off")
    left.set_xlabel("wavenumber k (rad/m)")
    left.set_ylabel("E(k) (m² per rad/m)")
    left.legend(fontsize=8)
    f = omega / (2 * math.pi)
    keep = (f > 0) & (e_omega > 0)
    right.loglog(f[keep], e_omega[keep] * 2 * math.pi, color="C1")
    right.set_xlabel("frequency f (Hz)")
    right.set_ylabel("E(f) (m² per Hz)")
    for axes in (left, right):
        axes.grid(True, which="both", alpha=0.3)
        _plain_log(axes)
    figure.suptitle(
        f"{results.maps.label}: energy spectra, mean square height "
        f"{np.trapezoid(e_k, k) * 1e18:.3g} nm² (up to the cut-off)",
        fontsize=10,
    )
    figure.subplots_adjust(left=0.1, right=0.98, bottom=0.12, top=0.88, wspace=0.25)
    _save(figure, path)


def _plain_log(axes: Axes, which: str = "x") -> None:
    """A log axis (``which``: ``"x"`` or ``"y"``) labelled in plain numbers (``200``,
    ``500``, ``1000``): matplotlib's ``3 x 10^2`` labels between the decades ran into each
    other on a decade of k, and its 7, 8, 9 on a ringdown's envelope. The 2s and 5s between
    decades are labelled where the axis spans under three decades."""
    low, high = axes.get_xlim() if which == "x" else axes.get_ylim()
    low, high = min(low, high), max(low, high)
    decades = math.log10(high / low) if low > 0 else math.inf

    def minor(value: float, _: int) -> str:
        if decades >= 3 or value <= 0:
            return ""
        leading = round(value / 10 ** math.floor(math.log10(value)), 6)
        return f"{value:g}" if leading in (2.0, 5.0) else ""

    axis = axes.xaxis if which == "x" else axes.yaxis
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_formatter(FuncFormatter(minor))


def mf_figure(results: WaveResults, path: Path) -> None:
    """``m_f.png`` (module docstring)."""
    mf = results.mf
    assert mf is not None
    figure = Figure(figsize=(8, 5))
    axes = figure.subplots()
    image = axes.pcolormesh(
        mf.m,
        mf.frequency,
        mf.power.T,
        norm=_log_norm(mf.power),
        shading="nearest",
        cmap=colormaps["viridis"].with_extremes(bad="black"),
    )
    for fit in results.partial_waves:
        axes.plot(fit.m, fit.frequency, "o", mfc="none", mec="red", ms=12)
    axes.set_xlabel("azimuthal number m (exp(i(mθ - ωt)))")
    axes.set_ylabel("frequency f (Hz)")
    figure.colorbar(image, ax=axes).set_label("power density (m²/Hz)")
    x0, y0 = results.centre or (0.0, 0.0)
    fitted = "circles: fitted" if results.partial_waves else "none fitted (see waves.json notes)"
    axes.set_title(
        f"(m, f) spectrum around ({x0 * 1e3:.2f}, {y0 * 1e3:.2f}) mm, "
        f"r {mf.radii[0] * 1e3:.3g}-{mf.radii[-1] * 1e3:.3g} mm; {fitted}",
        fontsize=9,
    )
    figure.subplots_adjust(left=0.09, right=0.97, bottom=0.11, top=0.92)
    _save(figure, path)


def partial_waves_figure(results: WaveResults, path: Path) -> None:
    """``partial_waves.png`` (module docstring)."""
    fits = results.partial_waves
    count = max(len(fits), 1)
    width, height = 4.2 * min(count, 4), 4.0 * math.ceil(count / 4)
    figure = Figure(figsize=(width, height))
    axes_list = np.atleast_1d(figure.subplots(math.ceil(count / 4), min(count, 4))).ravel()
    for axes, fit in zip(axes_list, fits, strict=False):
        r = fit.radii * 1e3
        kr = fit.wavenumber * fit.radii
        outgoing = np.abs(fit.outgoing * special.hankel1(fit.m, kr)) * 1e9
        incoming = np.abs(fit.incoming * special.hankel2(fit.m, kr)) * 1e9
        axes.plot(r, np.abs(fit.profile) * 1e9, ".", ms=3, color="k", label="measured |A|")
        axes.plot(r, np.abs(fit.model) * 1e9, color="C3", lw=1.2, label="fit")
        axes.plot(r, outgoing, "--", color="C0", lw=1.0, label="outgoing")
        axes.plot(r, incoming, ":", color="C2", lw=1.2, label="incoming")
        axes.set_xlabel("radius r (mm)")
        axes.set_ylabel("amplitude (nm)")
        axes.set_title(
            f"m={fit.m}, f={fit.frequency:.4g} Hz: in/out {fit.ratio:.3f} ± {fit.ratio_stderr:.2g}",
            fontsize=9,
        )
        axes.legend(fontsize=7)
    for axes in axes_list[len(fits) :]:
        axes.set_axis_off()
    figure.subplots_adjust(  # margins in inches, whatever the number of panels
        left=0.7 / width,
        right=1 - 0.15 / width,
        bottom=0.5 / height,
        top=1 - 0.4 / height,
        wspace=0.3,
        hspace=0.35,
    )
    _save(figure, path)


def ringdown_figure(results: WaveResults, path: Path) -> None:
    """``ringdown.png`` (module docstring)."""
    fit = results.ringdown
    assert fit is not None
    figure = Figure(figsize=(11, 4.5))
    left, right = figure.subplots(1, 2)
    series, model = fit.series * 1e9, fit.model * 1e9  # nm
    left.semilogy(fit.times, np.abs(series), ".", ms=2, color="k", label="band-passed |z|")
    left.semilogy(fit.times, np.abs(model), color="C3", label="fit C exp(-γ t), band-passed")
    _plain_log(left, "y")
    left.set_xlabel("time t (s)")
    left.set_ylabel("|z|, the rings combined (nm)")
    left.set_title("envelope", fontsize=9)
    left.legend(fontsize=8)
    right.plot(fit.times, series.real, ".", ms=3, color="k", label="Re z")
    right.plot(fit.times, model.real, color="C3", lw=0.8, label="fit")
    right.plot(fit.times, np.abs(model), color="0.6", lw=0.8, ls="--", label="± envelope")
    right.plot(fit.times, -np.abs(model), color="0.6", lw=0.8, ls="--")
    right.set_xlabel("time t (s)")
    right.set_ylabel("Re z (nm)")
    right.set_title("the first periods", fontsize=9)
    right.set_xlim(
        fit.times[0], fit.times[0] + min(fit.times[-1] - fit.times[0], 8 / fit.frequency)
    )
    right.legend(fontsize=8, loc="upper right")
    figure.suptitle(
        f"ringdown m={fit.m}, band {fit.band[0]:g}-{fit.band[1]:g} Hz: "
        f"f = {with_error(fit.frequency, fit.frequency_stderr)} Hz, "
        f"γ = {with_error(fit.decay, fit.decay_stderr)} 1/s, Q = {fit.quality:.3g}",
        fontsize=10,
    )
    figure.subplots_adjust(left=0.08, right=0.98, bottom=0.12, top=0.86, wspace=0.25)
    _save(figure, path)


def lockin_figure(results: WaveResults, path: Path) -> None:
    """``lockin.png`` (module docstring)."""
    lockin = results.lockin
    assert lockin is not None
    dy, dx = results.maps.pixel_size
    rows, cols = results.maps.shape
    x0, x1, y0, y1 = map_edges(rows, cols, dy * 1e3, dx * 1e3)
    extent = (x0, x1, y1, y0)
    panels = 2 + len(lockin.harmonics) - 1
    width = 4.2 * panels
    figure = Figure(figsize=(width, 4.0))
    axes_list = np.atleast_1d(figure.subplots(1, panels))
    amplitude = lockin.magnitude * 1e9
    image = axes_list[0].imshow(amplitude[0], extent=extent, cmap="viridis")
    figure.colorbar(image, ax=axes_list[0]).set_label("amplitude (nm)")
    axes_list[0].set_title(f"|A| at {lockin.frequency:.4g} Hz", fontsize=9)
    image = axes_list[1].imshow(
        lockin.phase[0], extent=extent, cmap="twilight", vmin=-np.pi, vmax=np.pi
    )
    figure.colorbar(image, ax=axes_list[1]).set_label("phase (rad)")
    axes_list[1].set_title("phase (h = |A| cos(ωt - phase))", fontsize=9)
    for axes, n, values in zip(axes_list[2:], lockin.harmonics[1:], amplitude[1:], strict=False):
        image = axes.imshow(values, extent=extent, cmap="viridis")
        figure.colorbar(image, ax=axes).set_label("amplitude (nm)")
        axes.set_title(f"|A| at harmonic {n} ({n * lockin.frequency:.4g} Hz)", fontsize=9)
    for axes in axes_list:
        axes.set_xlabel("x (mm)")
        axes.set_ylabel("y (mm)")
        if results.centre is not None:
            x0, y0 = results.centre
            axes.plot(x0 * 1e3, y0 * 1e3, "+", color="red", ms=10, mew=1.5, label="centre")
    if results.centre is not None:
        axes_list[0].legend(fontsize=7, loc="upper right")
    figure.subplots_adjust(
        left=0.6 / width, right=1 - 0.9 / width, bottom=0.14, top=0.9, wspace=0.45
    )
    _save(figure, path)


def _draw(results: WaveResults, plan: list[tuple[str, Drawer]], paths: dict[str, Path]) -> None:
    for name, draw in plan:
        draw(results, paths[name])


def draw_figures(results: WaveResults, paths: dict[str, Path], *, processes: int = 1) -> list[str]:
    """Draw the figures the results hold into ``paths[name]``; return the names drawn.

    With ``processes`` 2 or more (and ``fork``), every other figure is drawn in a forked
    child at the same time (matplotlib draws on one core); a child that fails has its
    figures drawn again here, so that its error is raised here.
    """
    plan: list[tuple[str, Drawer]] = [
        (name, draw)
        for name, draw, wanted in (
            ("omega_k.png", omega_k_figure, True),
            ("energy.png", energy_figure, True),
            ("m_f.png", mf_figure, results.mf is not None),
            ("partial_waves.png", partial_waves_figure, bool(results.partial_waves)),
            ("ringdown.png", ringdown_figure, results.ringdown is not None),
            ("lockin.png", lockin_figure, results.lockin is not None),
        )
        if wanted
    ]
    if processes < 2 or len(plan) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        _draw(results, plan, paths)
        return [name for name, _ in plan]
    theirs, ours = plan[1::2], plan[::2]
    child = multiprocessing.get_context("fork").Process(
        target=_draw, args=(results, theirs, paths), name="holoview-figures"
    )
    child.start()
    try:
        _draw(results, ours, paths)
    finally:
        child.join()
    if child.exitcode != 0:
        _draw(results, theirs, paths)
    return [name for name, _ in plan]
