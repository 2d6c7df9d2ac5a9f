"""``report.png``: what a person looks at first after a headless run.

Three parts, drawn with OpenCV (:mod:`holoview.headless.plotting`):

1. the spatial-frequency spectrum of the first processed frame (log magnitude,
   ``fx`` along columns, ``fy`` down the rows, cycles/pixel) with every processed
   peak circled at its window radius and labelled, its twin dotted, and the other
   detected peaks in grey;
2. the mean height change of each peak and the fused estimate over time, in nm, with
   the fitted line of the fused depth; the legend gives each peak's alpha and rate
   (um/min, with its standard error) and why a peak was left out of the fusion;
3. the delta-h map of every peak and the fused map of the last frame (nm, colour
   bar; grey where not trusted), titled with the reference mode.

Under them, in red, the run's notes (``summary.json``'s ``notes``): the caveats a
reader must not miss, such as an automatic identification whose global sign is
a guess.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from holoview.errors import OutputError, os_error_text
from holoview.headless.analysis import Analysis
from holoview.headless.inputs import Optics
from holoview.headless.pipeline import ProcessSettings, RunData, fuse_frame
from holoview.headless.plotting import (
    BLACK,
    GREY,
    PALETTE,
    WHITE,
    Axes,
    colour_bar,
    colour_image,
    dashed_segment,
    legend,
    padded_limits,
    text,
)
from holoview.processing.peaks.detection import Peak
from holoview.processing.series.rate_fits import format_rate

#: Canvas width, pixels.
WIDTH = 1700
#: Side of the spectrum panel and of each map, pixels.
SPECTRUM_SIDE = 470
MAP_SIDE = 230
#: Width of one map cell (map, colour bar, margins), pixels.
MAP_CELL = 320
#: Height of one line of the notes under the maps, pixels.
NOTE_LINE = 26
#: Colour of the notes (BGR): the caveats a reader must not miss.
NOTE_RED = (30, 30, 200)

REFERENCE_TITLES = {
    "relative": "against the previous frame",
    "absolute": "against the first frame",
    "synthetic": "against a plane wave (up to 2 pi)",
}


def _spectrum_panel(
    image: np.ndarray,
    spectrum: np.ndarray,
    *,
    detected: Sequence[Peak],
    analysis: Analysis,
    radii: Sequence[float],
    origin: tuple[int, int],
) -> None:
    left, top = origin
    rows, cols = spectrum.shape
    low, high = np.percentile(spectrum, (5.0, 99.99))
    grey = np.clip((spectrum - low) / max(high - low, 1e-12) * 255, 0, 255).astype(np.uint8)
    grey = cv2.resize(grey, (SPECTRUM_SIDE, SPECTRUM_SIDE), interpolation=cv2.INTER_AREA)
    image[top : top + SPECTRUM_SIDE, left : left + SPECTRUM_SIDE] = cv2.cvtColor(
        grey, cv2.COLOR_GRAY2BGR
    )
    # bin centres: column k (centred) is fx = (k - cols // 2) / cols
    x0, x1 = -(cols // 2) / cols - 0.5 / cols, (cols - cols // 2) / cols - 0.5 / cols
    y0, y1 = -(rows // 2) / rows - 0.5 / rows, (rows - rows // 2) / rows - 0.5 / rows
    axes = Axes(image, (left, top, SPECTRUM_SIDE, SPECTRUM_SIDE), (x0, x1), (y1, y0))
    axes.frame(
        xlabel="fx (cycles/pixel)",
        ylabel="fy (cycles/pixel)",
        title="spectrum of the first frame (log magnitude)",
        grid=False,
    )
    scale = SPECTRUM_SIDE / (x1 - x0)
    processed = {tuple(np.round(p.carrier, 6)) for p in analysis.peaks}
    for peak in detected:
        for sign in (1, -1):
            carrier = (sign * peak.carrier[0], sign * peak.carrier[1])
            if tuple(np.round(carrier, 6)) in processed:
                continue
            px, py = axes.to_px(*carrier)
            cv2.circle(image, (int(px), int(py)), 4, GREY, 1, cv2.LINE_AA)
    for j, peak in enumerate(analysis.peaks):
        radius = radii[j]
        colour = PALETTE[j % len(PALETTE)]
        px, py = axes.to_px(*peak.carrier)
        centre = (round(float(px)), round(float(py)))
        cv2.circle(image, centre, max(3, int(radius * scale)), colour, 2, cv2.LINE_AA)
        tx, ty = axes.to_px(-peak.carrier[0], -peak.carrier[1])
        cv2.circle(image, (int(tx), int(ty)), 3, colour, -1, cv2.LINE_AA)
        label_at = (centre[0] + int(radius * scale) + 4, centre[1] - 4)
        text(
            image,
            peak.label,
            (label_at[0] + 1, label_at[1] + 1),
            scale=0.5,
            colour=BLACK,
            thickness=2,
        )
        text(image, peak.label, label_at, scale=0.5, colour=WHITE, thickness=1)
    text(
        image,
        f"circles: each peak's window ({min(radii):.3g} to {max(radii):.3g} cycles/pixel); "
        "dots: twins; grey: other peaks",
        (left, top + SPECTRUM_SIDE + 62),
        scale=0.42,
    )


def _trend_panel(
    image: np.ndarray, data: RunData, analysis: Analysis, box: tuple[int, int, int, int]
) -> None:
    left, top, width, _height = box
    times = data.times
    shown = [j for j, p in enumerate(analysis.peaks) if p.used_in_fused] or list(
        range(len(analysis.peaks))
    )
    limits = [analysis.heights[:, j] for j in shown]
    if analysis.fused is not None:
        limits.append(analysis.fused)
    span_m = float(np.nanmax(np.abs(np.concatenate(limits)))) if limits else 0.0
    unit, factor = ("um", 1e6) if span_m > 5e-6 else ("nm", 1e9)
    ylim = padded_limits(np.concatenate(limits) * factor if limits else np.zeros(1))
    xlim = padded_limits(times, 0.0) if times.size > 1 else (-0.5, 0.5)
    axes = Axes(image, box, xlim, ylim)
    axes.frame(
        xlabel="time (s)",
        ylabel=f"mean height change ({unit})",
        title="depth trends (relative to the first frame)",
    )
    entries: list[tuple[str, tuple[int, int, int], int]] = []
    for j, peak in enumerate(analysis.peaks):
        colour = PALETTE[j % len(PALETTE)]
        axes.line(times, analysis.heights[:, j] * factor, colour, thickness=1)
        alpha = f"{peak.alpha:.4g}" if peak.alpha is not None else "?"
        rate = format_rate(peak.rate, peak.rate_stderr, ascii=True)
        entries.append((f"{peak.label} (alpha {alpha}): {rate}", colour, 1))
        if not peak.used_in_fused:
            reasons = [f for f in ("aliased_in_time", "weak", "unexplained") if f in peak.flags]
            entries.append((f"   not fused: {', '.join(reasons) or 'excluded'}", WHITE, 0))
    if analysis.fused is not None:
        axes.line(times, analysis.fused * factor, BLACK, thickness=2)
        entries.append((f"fused: {format_rate(*_fit(analysis), ascii=True)}", BLACK, 2))
        if analysis.fit is not None:
            ends = (float(times[0]), float(times[-1]))
            fit = analysis.fit
            dashed_segment(
                axes,
                ends,
                tuple((fit.intercept + fit.rate * t) * factor for t in ends),  # type: ignore[arg-type]
                (0, 0, 200),
                thickness=2,
            )
            entries.append(("fitted line of the fused depth", (0, 0, 200), 2))
    legend(image, (left + width + 20, top + 10), entries)
    if times.size < 3:
        text(image, "fewer than three frames: no trend", (left + 20, top + 30), scale=0.55)


def _fit(analysis: Analysis) -> tuple[float | None, float | None]:
    fit = analysis.fit
    return (fit.rate, fit.stderr) if fit is not None else (None, None)


def _last_maps(data: RunData, analysis: Analysis) -> list[tuple[str, np.ndarray, str]]:
    """``(title, values, unit)`` of each peak's last map, converted to nm, and the fused one."""
    panels = []
    heights: list[np.ndarray | None] = []
    for peak, values in zip(analysis.peaks, data.last_maps, strict=True):
        metres = None
        if values is not None and data.maps_in_metres:
            metres = values
        elif values is not None and peak.map_scale is not None:
            metres = values * np.float32(peak.map_scale)
        heights.append(metres)
        if metres is not None:
            title = peak.label if peak.used_in_fused else f"{peak.label} (not fused)"
            panels.append((title, metres * 1e9, "nm"))
        elif values is not None:
            panels.append((f"{peak.label} phase", values, "rad"))
    found = np.flatnonzero(data.frames == data.last_frame)
    fused = None
    if found.size:
        fused = fuse_frame(data, int(found[0]), heights, analysis.map_fusion_scales())
    if fused is not None:
        moved = any(d.measured and d.shift != (0.0, 0.0) for d in data.displacements)
        title = f"fused (on {analysis.peaks[0].label}'s grid)" if moved else "fused"
        panels.append((title, fused * 1e9, "nm"))
    return panels


def _map_panels(
    image: np.ndarray,
    panels: list[tuple[str, np.ndarray, str]],
    top: int,
    frame_shape: tuple[int, int],
    caption: str,
) -> None:
    rows, cols = frame_shape
    h = int(MAP_SIDE * rows / max(rows, cols))
    w = int(MAP_SIDE * cols / max(rows, cols))
    per_row = max(1, (WIDTH - 60) // MAP_CELL)
    for k, (title, values, unit) in enumerate(panels):
        left = 60 + (k % per_row) * MAP_CELL
        y = top + (k // per_row) * (MAP_SIDE + 70)
        finite = values[np.isfinite(values)]
        low, high = (
            (float(np.percentile(finite, 1)), float(np.percentile(finite, 99)))
            if finite.size
            else (-1.0, 1.0)
        )
        if high <= low:
            low, high = low - 1.0, high + 1.0
        picture = cv2.resize(
            colour_image(values, low, high), (w, h), interpolation=cv2.INTER_NEAREST
        )
        image[y : y + h, left : left + w] = picture
        cv2.rectangle(image, (left, y), (left + w, y + h), BLACK, 1)
        text(image, title, (left, y - 8), scale=0.55)
        colour_bar(image, (left + w + 10, y, 14, h), low, high, label=unit)
    text(image, caption, (60, top - 34), scale=0.5)


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
    """Draw the report (module docstring) and write it as a PNG.

    Parameters
    ----------
    path : Path
        The PNG to write.
    spectrum : ndarray, shape (rows, cols)
        Centred log-magnitude spectrum of the first frame
        (:func:`holoview.processing.fourier.spectrum.display_spectrum`).
    detected : sequence of Peak
        The peaks detected in the first frame.
    data, analysis : RunData, Analysis
        The run's series and results.
    settings : ProcessSettings
    optics : Optics
    title : str
        First line of the figure (the input and its frames).
    """
    panels = _last_maps(data, analysis)
    per_row = max(1, (WIDTH - 60) // MAP_CELL)
    map_rows = -(-len(panels) // per_row)
    maps_top = 100 + SPECTRUM_SIDE + 150
    notes_top = maps_top + map_rows * (MAP_SIDE + 70)
    height = notes_top + NOTE_LINE * len(analysis.notes) + 20
    image = np.full((height, WIDTH, 3), 255, np.uint8)
    text(image, title, (20, 32), scale=0.7, thickness=2)
    fit_text = format_rate(*_fit(analysis), ascii=True)
    n2 = f"{optics.n2:.4g}" if optics.n2 is not None else "?"
    text(
        image,
        f"fused depth rate: {fit_text}   |   wavelength {(optics.wavelength_m or 0) * 1e9:.1f} nm, "
        f"n1 {optics.n1:.4g}, n2 {n2}, window {settings.window}, reference {settings.reference}",
        (20, 62),
        scale=0.55,
    )
    _spectrum_panel(
        image,
        spectrum,
        detected=detected,
        analysis=analysis,
        radii=[w.radius for w in data.windows] or [data.radius] * len(analysis.peaks),
        origin=(100, 100),
    )
    _trend_panel(image, data, analysis, (720, 100, 540, SPECTRUM_SIDE))
    rows, cols = spectrum.shape
    field_text = ""
    if optics.pixel_pitch_m is not None:
        field_text = (
            f", field {cols * optics.pixel_pitch_m * 1e3:.3g} x "
            f"{rows * optics.pixel_pitch_m * 1e3:.3g} mm"
        )
    _map_panels(
        image,
        panels,
        maps_top,
        (rows, cols),
        f"delta-h maps of frame {data.last_frame}, {REFERENCE_TITLES[settings.reference]}"
        f"{field_text}; grey: untrusted",
    )
    for i, note in enumerate(analysis.notes):
        text(
            image,
            f"note: {note}",
            (20, notes_top + NOTE_LINE * (i + 1)),
            scale=0.55,
            colour=NOTE_RED,
        )
    encoded, png = cv2.imencode(".png", image)  # in memory: libpng prints nothing
    if not encoded:
        raise OutputError("cannot encode report.png")
    try:
        path.write_bytes(png.tobytes())
    except OSError as exc:
        raise OutputError(f"cannot write report.png: {os_error_text(exc)}") from exc
