"""``holoview simulate --png``'s figure: a simulated frame beside its spectrum, the carriers
the optics predict marked on it.

Matplotlib is imported when the figure is drawn: ``simulate`` without ``--png`` does
without it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from matplotlib.figure import Figure

    from holoview.optics.families import Family

__all__ = ["spectrum_figure"]


def spectrum_figure(
    frame: np.ndarray,
    families: list[Family],
    *,
    pixel_pitch_m: float,
    title: str,
    amplitudes: dict[str, float] | None = None,
) -> Figure:
    """Return a figure: the frame beside its log spectrum, predicted carriers marked.

    The frame's axes are in mm on the object side (``pixel_pitch_m`` a pixel), the
    spectrum's in cycles/pixel (cycles/mm on the opposite axes). Each family whose
    peak (``amplitudes[label]``, default its own amplitude) is at least
    :data:`~holoview.engine.true_labels.VISIBLE_AMPLITUDE` gets a circle at its
    observed carrier (stored twin) labelled with its name (families on one carrier
    share a circle), and a dot at its conjugate twin: red where the carrier is past
    Nyquist (drawn folded), orange for a second order, green for the rest.

    Parameters
    ----------
    frame : ndarray, shape (rows, cols)
        Raw camera values.
    families : list of Family
        The setup's predicted families (:func:`holoview.optics.families.predict_families`).
    pixel_pitch_m : float
        Object-side pixel pitch, m.
    title : str
        The figure's first line.
    amplitudes : dict of str to float, optional
        Each family's visible peak amplitude.
    """
    import numpy as np
    from matplotlib import patheffects

    from holoview.engine.true_labels import VISIBLE_AMPLITUDE
    from holoview.headless.results.figures import map_edges, new_figure, spectrum_edges

    data = frame.astype(np.float64)
    rows, cols = frame.shape
    hann = np.outer(np.hanning(rows), np.hanning(cols))
    power = np.log10(np.abs(np.fft.fftshift(np.fft.fft2((data - data.mean()) * hann))) + 1e-12)
    figure = new_figure(13.66, 6.4)
    image_axes = figure.add_axes((0.045, 0.09, 0.34, 0.74))
    spectrum_axes = figure.add_axes((0.55, 0.09, 0.32, 0.74))
    mm = pixel_pitch_m * 1e3
    low, high = np.percentile(data, (0.5, 99.5))
    x0, x1, y0, y1 = map_edges(rows, cols, mm, mm)  # pixel (r, c) at (c, r) pitches
    shown = image_axes.imshow(data, cmap="gray", vmin=low, vmax=high, extent=(x0, x1, y1, y0))
    # the fringes alias at this scale: the centre's, pixel for pixel, in an inset
    side = min(48, rows, cols)
    top_row, left_col = (rows - side) // 2, (cols - side) // 2
    inset = image_axes.inset_axes((0.62, 0.62, 0.36, 0.36))
    inset.imshow(
        data[top_row : top_row + side, left_col : left_col + side],
        cmap="gray",
        vmin=low,
        vmax=high,
        interpolation="nearest",
    )
    inset.set_xticks([])
    inset.set_yticks([])
    inset.set_title(
        f"centre, {side} x {side} pixels",
        fontsize=8,
        pad=2,
        bbox={"facecolor": "white", "edgecolor": "none", "pad": 1},
    )
    figure.colorbar(shown, ax=image_axes, fraction=0.046, pad=0.03, label="camera counts")
    image_axes.set_xlabel("x (mm)")
    image_axes.set_ylabel("y (mm)")
    image_axes.set_title("hologram (raw camera values)", fontsize=11)
    x0, x1, y0, y1 = spectrum_edges(rows, cols)
    low, high = np.percentile(power, (1.0, 99.99))
    spectrum_axes.imshow(
        power,
        cmap="gray",
        vmin=low,
        vmax=high,
        extent=(x0, x1, y1, y0),
        interpolation="antialiased",
    )
    marks: dict[tuple[float, float], list[Family]] = {}
    for family in families:
        size_of_peak = family.amplitude if amplitudes is None else amplitudes[family.label]
        if size_of_peak >= VISIBLE_AMPLITUDE:
            key = (round(family.observed_carrier[0], 4), round(family.observed_carrier[1], 4))
            marks.setdefault(key, []).append(family)
    outline = [patheffects.withStroke(linewidth=2.5, foreground="black")]
    kinds = {
        "#E03030": "past Nyquist (folded)",
        "#FFA000": "second order",
        "#30D030": "first order",
    }
    for (fx, fy), group in marks.items():
        first = group[0]
        colour = (
            "#E03030" if first.aliased else "#FFA000" if first.kind == "second-order" else "#30D030"
        )
        spectrum_axes.plot([fx], [fy], "o", ms=13, mfc="none", mec=colour, mew=1.4)
        spectrum_axes.plot([-fx], [-fy], "o", ms=3, color=colour)
        spectrum_axes.annotate(
            "/".join(f.label for f in group),
            (fx, fy),
            xytext=(8, 6),
            textcoords="offset points",
            color=colour,
            fontsize=9,
            path_effects=outline,
        )
    for colour, kind in kinds.items():
        spectrum_axes.plot([], [], "o", ms=8, mfc="none", mec=colour, mew=1.4, label=kind)
    spectrum_axes.legend(
        loc="lower right", fontsize=8, facecolor="0.1", edgecolor="0.5", labelcolor="white"
    )
    spectrum_axes.set_xlim(x0, x1)
    spectrum_axes.set_ylim(y1, y0)
    spectrum_axes.set_xlabel("$f_x$ (cycles/pixel)")
    spectrum_axes.set_ylabel("$f_y$ (cycles/pixel)")
    per_mm = 1.0 / mm
    top = spectrum_axes.secondary_xaxis(
        "top", functions=(lambda f: np.asarray(f) * per_mm, lambda k: np.asarray(k) / per_mm)
    )
    top.set_xlabel("cycles/mm (object side)")
    spectrum_axes.set_title(
        "spectrum (log magnitude, Hann window): predicted carriers; dots: twins", fontsize=11
    )
    figure.text(0.01, 0.98, title, fontsize=13, fontweight="bold", va="top")
    return figure
