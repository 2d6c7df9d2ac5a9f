"""The report of a headless run (``report.png``, or PDF or SVG): what a person looks at first.

Drawn with matplotlib on its Agg canvas (:mod:`holoview.headless.results.figures`), 1366
pixels wide as a PNG, in three parts:

1. the spatial-frequency spectrum of the first processed frame (log magnitude,
   ``fx`` along columns, ``fy`` down the rows, cycles/pixel; cycles/mm on the
   opposite axes when the pixel pitch is known) with every processed peak circled at
   its window radius and labelled, its twin dotted, and the other detected peaks in
   grey;
2. the mean height change of each peak and the fused estimate against time, in nm
   (um past 5 um), with the fitted line of the fused depth; the legend gives each
   peak's alpha and rate (um/min, with its standard error) and why a peak was left
   out of the fusion;
3. the delta-h map of every peak and the fused map of the last frame, in nm (each
   with its colour bar, from its 1st to 99th percentile), axes in mm on the object side
   (camera pixels without a pixel pitch), grey where not trusted, titled with the
   reference mode.

Under them, in red, the run's notes (``summary.json``'s ``notes``): the caveats a
reader must not miss, such as an automatic identification whose global sign is
a guess.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps, patheffects
from matplotlib.axes import Axes
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from holoview.headless.analysis import Analysis
from holoview.headless.inputs import Optics
from holoview.headless.results.figures import (
    DPI,
    map_edges,
    new_figure,
    save_figure,
    spectrum_edges,
)
from holoview.headless.run_data import RunData
from holoview.headless.settings import ProcessSettings
from holoview.processing.peaks.detection import Peak
from holoview.processing.series.rate_fits import format_rate

#: Figure width, inches (1366 pixels in a PNG).
WIDTH_IN = 13.66
#: Height of the header (title and the run's line), inches.
HEADER_IN = 0.95
#: Side of the spectrum and trends panels, inches.
PANEL_IN = 4.1
#: The spectrum is shown averaged over blocks of bins, as many as fit in one of the
#: panel's pixels at the figure's resolution: matplotlib resamples the image it is given in
#: float64 RGBA, which at 1024^2 raised the run's peak memory by about 45 MB (the report
#: made 50 of a 1024^2 process's 275 MB); averaged 2 x 2, what it shows is the same.
SPECTRUM_PIXELS = round(PANEL_IN * DPI)
#: Side of one map, inches, and the maps in a row.
MAP_IN = 2.05
MAPS_PER_ROW = 4
#: Height of one line of notes, inches.
NOTE_IN = 0.24
#: Characters in a line of notes before it wraps.
NOTE_WIDTH = 150

#: Line colours, colour-blind friendly (Okabe and Ito, 2008).
PALETTE = (
    "#0072B2",  # blue
    "#D55E00",  # vermilion
    "#009E73",  # bluish green
    "#CC79A7",  # reddish purple
    "#E69F00",  # orange
    "#56B4E9",  # sky blue
    "#F0E442",  # yellow
    "#3C3C3C",  # dark grey
)
FIT_COLOUR = "#C00000"
NOTE_COLOUR = "#B00000"

REFERENCE_TITLES = {
    "relative": "against the previous frame",
    "absolute": "against the first frame",
    "synthetic": "against a plane wave (up to 2\u03c0)",
}

#: A white outline under text drawn over an image.
OUTLINE = [patheffects.withStroke(linewidth=2.5, foreground="black")]


@dataclass(frozen=True)
class MapPanel:
    """One map of the last frame: title, values (nm, or rad) and their unit."""

    title: str
    values: np.ndarray
    unit: str


class _Layout:
    """Axes placed in inches from the figure's top-left corner."""

    def __init__(self, figure: Figure, height_in: float) -> None:
        self.figure = figure
        self.height_in = height_in

    def axes(self, left: float, top: float, width: float, height: float) -> Axes:
        rect = (
            left / WIDTH_IN,
            1 - (top + height) / self.height_in,
            width / WIDTH_IN,
            height / self.height_in,
        )
        return self.figure.add_axes(rect)

    def text(self, left: float, top: float, content: str, **style: Any) -> None:
        self.figure.text(
            left / WIDTH_IN, 1 - top / self.height_in, content, va="top", ha="left", **style
        )


def _spectrum_panel(
    axes: Axes,
    spectrum: np.ndarray,
    *,
    detected: Sequence[Peak],
    analysis: Analysis,
    radii: Sequence[float],
    pixel_pitch_m: float | None,
) -> None:
    rows, cols = spectrum.shape
    x0, x1, y0, y1 = spectrum_edges(rows, cols)
    factor = max(1, min(rows, cols) // SPECTRUM_PIXELS)
    shown = block_mean(spectrum, factor)
    # the bins beyond the last whole block are left out of the image
    x1 -= (cols - shown.shape[1] * factor) / cols
    y1 -= (rows - shown.shape[0] * factor) / rows
    low, high = np.percentile(shown, (5.0, 99.99))
    axes.imshow(
        shown,
        cmap="gray",
        vmin=low,
        vmax=high,
        extent=(x0, x1, y1, y0),
        origin="upper",
        interpolation="antialiased",
    )
    axes.set_xlabel("$f_x$ (cycles/pixel)")
    axes.set_ylabel("$f_y$ (cycles/pixel)")
    processed = {tuple(np.round(p.carrier, 6)) for p in analysis.peaks}
    others = [
        (sign * p.carrier[0], sign * p.carrier[1])
        for p in detected
        for sign in (1, -1)
        if tuple(np.round((sign * p.carrier[0], sign * p.carrier[1]), 6)) not in processed
    ]
    if others:
        fx, fy = np.array(others).T
        axes.plot(fx, fy, "o", ms=6, mfc="none", mec="0.6", mew=1)
    for j, peak in enumerate(analysis.peaks):
        radius = radii[j]
        colour = PALETTE[j % len(PALETTE)]
        fx, fy = peak.carrier
        axes.add_patch(Circle((fx, fy), radius, fill=False, ec=colour, lw=1.8))
        axes.plot([-fx], [-fy], "o", ms=4, color=colour)
        axes.text(
            fx + radius * 0.75,
            fy - radius * 0.75,
            peak.label,
            color="white",
            fontsize=10,
            fontweight="bold",
            path_effects=OUTLINE,
        )
    axes.set_xlim(x0, x1)
    axes.set_ylim(y1, y0)
    if pixel_pitch_m is not None:
        per_mm = 1e-3 / pixel_pitch_m  # cycles/pixel to cycles/mm

        top = axes.secondary_xaxis(
            "top", functions=(lambda f: np.asarray(f) * per_mm, lambda k: np.asarray(k) / per_mm)
        )
        top.set_xlabel("cycles/mm (object side)")
    low, high = f"{min(radii):.3g}", f"{max(radii):.3g}"
    span = low if low == high else f"{low} to {high}"
    axes.set_title(  # within the panel's width: a longer line ran off the figure's edge
        f"spectrum of the first frame (log magnitude)\n"
        f"circles: windows ({span} cycles/px); dots: twins; grey: others",
        fontsize=10,
    )


def block_mean(image: np.ndarray, factor: int) -> np.ndarray:
    """``image`` averaged over blocks of ``factor`` x ``factor`` pixels (float32).

    The rows and columns beyond the last whole block are left out; ``factor`` 1 gives
    the image itself.

    Examples
    --------
    >>> block_mean(np.arange(20.0).reshape(4, 5), 2).tolist()
    [[3.0, 5.0], [13.0, 15.0]]
    """
    if factor <= 1:
        return image
    rows, cols = image.shape[0] // factor, image.shape[1] // factor
    blocks = image[: rows * factor, : cols * factor].reshape(rows, factor, cols, factor)
    mean: np.ndarray = blocks.mean(axis=(1, 3), dtype=np.float64)
    return mean.astype(np.float32)


def _fit(analysis: Analysis) -> tuple[float | None, float | None]:
    fit = analysis.fit
    return (fit.rate, fit.stderr) if fit is not None else (None, None)


def _trend_panel(axes: Axes, data: RunData, analysis: Analysis) -> None:
    times = data.times
    shown = [j for j, p in enumerate(analysis.peaks) if p.used_in_fused] or list(
        range(len(analysis.peaks))
    )
    limits = [analysis.heights[:, j] for j in shown]
    if analysis.fused is not None:
        limits.append(analysis.fused)
    values = np.concatenate(limits) if limits else np.zeros(1)
    finite = values[np.isfinite(values)]
    span_m = float(np.max(np.abs(finite))) if finite.size else 0.0
    unit, factor = ("\u00b5m", 1e6) if span_m > 5e-6 else ("nm", 1e9)
    for j, peak in enumerate(analysis.peaks):
        alpha = f"{peak.alpha:.4g}" if peak.alpha is not None else "?"
        label = f"{peak.label} (\u03b1 {alpha}): {format_rate(peak.rate, peak.rate_stderr)}"
        if not peak.used_in_fused:
            reasons = [f for f in ("aliased_in_time", "weak", "unexplained") if f in peak.flags]
            label += f"\n    not fused: {', '.join(reasons) or 'excluded'}"
        axes.plot(
            times,
            analysis.heights[:, j] * factor,
            color=PALETTE[j % len(PALETTE)],
            lw=1,
            ls="-" if peak.used_in_fused else ":",
            label=label,
        )
    if analysis.fused is not None:
        axes.plot(
            times,
            analysis.fused * factor,
            color="black",
            lw=2,
            label=f"fused: {format_rate(*_fit(analysis))}",
        )
        fit = analysis.fit
        if fit is not None and times.size:
            ends = np.array([times[0], times[-1]])
            axes.plot(
                ends,
                (fit.intercept + fit.rate * ends) * factor,
                color=FIT_COLOUR,
                lw=1.6,
                ls="--",
                label="fitted line of the fused depth",
            )
    if finite.size and np.ptp(finite) > 0:
        low, high = float(finite.min()) * factor, float(finite.max()) * factor
        pad = (high - low) * 0.06
        axes.set_ylim(low - pad, high + pad)
    else:
        axes.set_ylim(-1.0, 1.0)
    axes.ticklabel_format(axis="both", useOffset=False)
    if times.size > 1:
        axes.set_xlim(float(times[0]), float(times[-1]))
    if times.size < 3:
        axes.text(0.05, 0.9, "fewer than three frames: no trend", transform=axes.transAxes)
    axes.grid(True, color="0.9")
    axes.set_xlabel("time (s)")
    axes.set_ylabel(f"mean height change ({unit})")
    axes.set_title("depth trends (relative to the first frame)", fontsize=10)
    axes.legend(
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        fontsize=9,
        frameon=False,
        borderaxespad=0.0,
        handlelength=2.2,
    )


def _last_maps(data: RunData, analysis: Analysis) -> list[MapPanel]:
    """Each peak's last map in nm (else its phase in rad), and the fused one: the maps step's."""
    panels = []
    for peak, values, unit in zip(analysis.peaks, data.last_maps, data.map_units, strict=True):
        if values is None:
            continue
        if unit == "m":
            title = peak.label if peak.label in data.fused_labels else f"{peak.label} (not fused)"
            panels.append(MapPanel(title, values * 1e9, "nm"))
        else:
            panels.append(MapPanel(f"{peak.label} phase", values, "rad"))
    if data.last_fused is not None:
        moved = any(d.measured and d.shift != (0.0, 0.0) for d in data.displacements)
        title = f"fused (on {analysis.peaks[0].label}'s grid)" if moved else "fused"
        panels.append(MapPanel(title, data.last_fused * 1e9, "nm"))
    return panels


def _limits(values: Sequence[np.ndarray]) -> tuple[float, float]:
    """The 1st and 99th percentiles of the finite values, (-1, 1) if none."""
    pooled = np.concatenate([v[np.isfinite(v)].ravel() for v in values] or [np.zeros(0)])
    if pooled.size == 0:
        return -1.0, 1.0
    low, high = (float(x) for x in np.percentile(pooled, (1.0, 99.0)))
    if high <= low:
        low, high = low - 1.0, high + 1.0
    return low, high


def _map_panels(
    layout: _Layout,
    panels: list[MapPanel],
    top: float,
    frame_shape: tuple[int, int],
    pixel_pitch_m: float | None,
) -> None:
    rows, cols = frame_shape
    scale, unit = (pixel_pitch_m * 1e3, "mm") if pixel_pitch_m is not None else (1.0, "pixels")
    side = max(rows, cols)
    width, height = MAP_IN * cols / side, MAP_IN * rows / side
    step = (WIDTH_IN - 0.75) / MAPS_PER_ROW
    for k, panel in enumerate(panels):
        left = 0.75 + (k % MAPS_PER_ROW) * step
        y = top + (k // MAPS_PER_ROW) * (MAP_IN + 0.75)
        axes = layout.axes(left, y, width, height)
        if panel.unit == "nm":
            cmap, norm, label = "viridis", Normalize(*_limits([panel.values])), "\u0394h (nm)"
        else:
            cmap, norm, label = "twilight", Normalize(-np.pi, np.pi), "phase (rad)"
        # a map pixel stands where results.h5 puts it: (c, r) map steps from the corner
        r, c = panel.values.shape
        x0, x1, y0, y1 = map_edges(r, c, rows * scale / r, cols * scale / c)
        shown = axes.imshow(
            np.ma.masked_invalid(panel.values),
            cmap=colormaps[cmap].with_extremes(bad="0.6"),
            norm=norm,
            extent=(x0, x1, y1, y0),
            interpolation="nearest",
        )
        bar = layout.axes(left + width + 0.08, y, 0.1, height)
        layout.figure.colorbar(shown, cax=bar, extend="both" if panel.unit == "nm" else "neither")
        bar.tick_params(labelsize=8)
        bar.set_ylabel(label, fontsize=9)
        axes.set_title(panel.title, fontsize=10)
        axes.set_xlabel(f"x ({unit})", fontsize=9)
        if k % MAPS_PER_ROW == 0:
            axes.set_ylabel(f"y ({unit})", fontsize=9)
        axes.tick_params(labelsize=8)


def write_report(
    path: Path,
    *,
    spectrum: np.ndarray,
    detected: Sequence[Peak],
    data: RunData,
    analysis: Analysis,
    settings: ProcessSettings,
    optics: Optics,
    title: str,
) -> None:
    """Draw the report (module docstring) and write it in the format of ``path``'s suffix.

    Parameters
    ----------
    path : Path
        The file to write, ``.png``, ``.pdf`` or ``.svg``.
    spectrum : ndarray, shape (rows, cols)
        Centred log-magnitude spectrum of the first frame
        (:func:`holoview.processing.fourier.spectrum.display_spectrum`).
    detected : sequence of Peak
        The peaks detected in the first frame.
    data, analysis : RunData, Analysis
        The run's series and results.
    settings : ProcessSettings
    optics : Optics
        The optics used (wavelength, indices, pixel pitch).
    title : str
        First line of the figure (the input and its frames).

    Raises
    ------
    OutputError
        The file could not be written.
    """
    panels = _last_maps(data, analysis)
    map_rows = -(-len(panels) // MAPS_PER_ROW)
    maps_top = HEADER_IN + PANEL_IN + 1.75
    notes = [
        line
        for note in analysis.notes
        for line in textwrap.wrap(f"note: {note}", NOTE_WIDTH, subsequent_indent="    ")
    ]
    notes_top = maps_top + map_rows * (MAP_IN + 0.75) + 0.2
    height_in = notes_top + NOTE_IN * len(notes) + 0.2
    figure = new_figure(WIDTH_IN, height_in)
    layout = _Layout(figure, height_in)
    layout.text(0.2, 0.18, title, fontsize=14, fontweight="bold")
    n2 = f"{optics.n2:.4g}" if optics.n2 is not None else "?"
    wavelength = f"{optics.wavelength_m * 1e9:.1f} nm" if optics.wavelength_m else "?"
    layout.text(
        0.2,
        0.5,
        f"fused depth rate: {format_rate(*_fit(analysis))}    |    wavelength {wavelength}, "
        f"n1 {optics.n1:.4g}, n2 {n2}, window {settings.window}, "
        f"reference {settings.reference}",
        fontsize=11,
    )
    _spectrum_panel(
        layout.axes(0.8, HEADER_IN + 0.55, PANEL_IN, PANEL_IN),
        spectrum,
        detected=detected,
        analysis=analysis,
        radii=[w.radius for w in data.windows] or [data.radius] * len(analysis.peaks),
        pixel_pitch_m=optics.pixel_pitch_m,
    )
    _trend_panel(layout.axes(5.75, HEADER_IN + 0.55, 3.7, PANEL_IN), data, analysis)
    rows, cols = spectrum.shape
    field = ""
    if optics.pixel_pitch_m is not None:
        field = (
            f", field {cols * optics.pixel_pitch_m * 1e3:.3g} \u00d7 "
            f"{rows * optics.pixel_pitch_m * 1e3:.3g} mm"
        )
    reference = REFERENCE_TITLES.get(str(settings.reference), str(settings.reference))
    if panels:
        layout.text(
            0.2,
            maps_top - 0.62,
            f"\u0394h maps of frame {data.last_frame}, {reference}{field}; grey: untrusted",
            fontsize=11,
        )
    _map_panels(layout, panels, maps_top, (rows, cols), optics.pixel_pitch_m)
    for i, line in enumerate(notes):
        layout.text(0.2, notes_top + NOTE_IN * i, line, fontsize=10, color=NOTE_COLOUR)
    save_figure(figure, path, name=f"report{path.suffix}")
