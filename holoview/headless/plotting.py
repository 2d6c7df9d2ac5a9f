"""Small plotting on OpenCV images: axes with ticks and labels, lines, text, colour maps.

Enough for the report of a headless run without matplotlib or Qt. Images are BGR
``uint8`` arrays; positions are pixels, origin top-left.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np

FONT = cv2.FONT_HERSHEY_SIMPLEX
BLACK = (0, 0, 0)
GREY = (150, 150, 150)
LIGHT = (225, 225, 225)
WHITE = (255, 255, 255)

#: Distinct line colours (BGR), colour-blind friendly (Okabe and Ito, 2008).
PALETTE = (
    (178, 114, 0),  # blue
    (0, 94, 213),  # vermilion
    (115, 158, 0),  # bluish green
    (167, 121, 204),  # reddish purple
    (0, 159, 230),  # orange
    (233, 180, 86),  # sky blue
    (66, 228, 240),  # yellow
    (60, 60, 60),  # dark grey
)


def text(
    image: np.ndarray,
    content: str,
    origin: tuple[int, int],
    *,
    scale: float = 0.5,
    colour: tuple[int, int, int] = BLACK,
    thickness: int = 1,
    align: str = "left",
    valign: str = "baseline",
) -> None:
    """Draw ``content`` at ``origin``.

    ``align`` is left, centre or right; ``valign`` baseline, middle or top.
    """
    (width, height), _ = cv2.getTextSize(content, FONT, scale, thickness)
    x, y = origin
    if align == "centre":
        x -= width // 2
    elif align == "right":
        x -= width
    if valign == "middle":
        y += height // 2
    elif valign == "top":
        y += height
    cv2.putText(image, content, (int(x), int(y)), FONT, scale, colour, thickness, cv2.LINE_AA)


def vertical_text(
    image: np.ndarray, content: str, centre: tuple[int, int], *, scale: float = 0.5
) -> None:
    """Draw ``content`` rotated 90 degrees counter-clockwise, centred at ``centre``."""
    (width, height), base = cv2.getTextSize(content, FONT, scale, 1)
    patch = np.full((height + base + 4, width + 4, 3), 255, np.uint8)
    cv2.putText(patch, content, (2, height + 2), FONT, scale, BLACK, 1, cv2.LINE_AA)
    patch = cv2.rotate(patch, cv2.ROTATE_90_COUNTERCLOCKWISE)
    h, w = patch.shape[:2]
    y0, x0 = centre[1] - h // 2, centre[0] - w // 2
    region = image[y0 : y0 + h, x0 : x0 + w]
    np.minimum(region, patch[: region.shape[0], : region.shape[1]], out=region)


def nice_ticks(low: float, high: float, count: int = 5) -> list[float]:
    """Round tick values covering ``[low, high]``, about ``count`` of them."""
    if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
        return [low]
    raw = (high - low) / max(count, 1)
    power = 10 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 2.5, 5, 10) if m * power >= raw)
    first = math.ceil(low / step - 1e-9) * step
    ticks = []
    value = first
    while value <= high + 1e-9 * step:
        ticks.append(0.0 if abs(value) < 1e-12 * step else value)
        value += step
    return ticks


def tick_labels(ticks: Sequence[float]) -> list[str]:
    """Labels of evenly spaced ticks with just enough decimals to tell them apart."""
    if len(ticks) < 2:
        return [f"{t:.4g}" for t in ticks]
    step = abs(ticks[1] - ticks[0])
    decimals = max(0, -math.floor(math.log10(step)))
    if abs(round(step * 10**decimals) - step * 10**decimals) > 1e-6:
        decimals += 1
    big = max(abs(t) for t in ticks)
    if big >= 1e6 or (big < 1e-3 and big > 0):
        return [f"{t:.3g}" for t in ticks]
    return [f"{t:.{decimals}f}" for t in ticks]


def padded_limits(values: np.ndarray, fraction: float = 0.05) -> tuple[float, float]:
    """``(low, high)`` of the finite values, widened by ``fraction``; (-1, 1) if none."""
    finite = np.asarray(values, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return -1.0, 1.0
    low, high = float(finite.min()), float(finite.max())
    if high - low < 1e-12 * max(abs(low), abs(high), 1e-30):
        span = max(abs(low), 1.0) * 0.1
        return low - span, high + span
    pad = (high - low) * fraction
    return low - pad, high + pad


class Axes:
    """A plotting area on an image: data limits, a pixel rectangle, ticks and labels.

    Parameters
    ----------
    image : ndarray
        The BGR canvas drawn on.
    box : tuple of int
        ``(left, top, width, height)`` of the data area, pixels.
    xlim, ylim : tuple of float
        Data limits along x (left to right) and y (bottom to top).
    """

    def __init__(
        self,
        image: np.ndarray,
        box: tuple[int, int, int, int],
        xlim: tuple[float, float],
        ylim: tuple[float, float],
    ) -> None:
        self.image = image
        self.left, self.top, self.width, self.height = box
        self.xlim, self.ylim = xlim, ylim

    def to_px(self, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Data coordinates to pixel coordinates (float arrays)."""
        x0, x1 = self.xlim
        y0, y1 = self.ylim
        px = self.left + (np.asarray(x, dtype=np.float64) - x0) / (x1 - x0) * self.width
        py = self.top + (1 - (np.asarray(y, dtype=np.float64) - y0) / (y1 - y0)) * self.height
        return px, py

    def frame(self, *, xlabel: str, ylabel: str, title: str = "", grid: bool = True) -> None:
        """Draw the box, ticks, tick labels, grid, axis labels and title."""
        img = self.image
        right, bottom = self.left + self.width, self.top + self.height
        xticks = nice_ticks(min(self.xlim), max(self.xlim), count=max(3, self.width // 110))
        for value, label in zip(xticks, tick_labels(xticks), strict=True):
            px = round(float(self.to_px(value, self.ylim[0])[0]))
            if grid:
                cv2.line(img, (px, self.top), (px, bottom), LIGHT, 1)
            cv2.line(img, (px, bottom), (px, bottom + 5), BLACK, 1)
            text(img, label, (px, bottom + 8), scale=0.42, align="centre", valign="top")
        yticks = nice_ticks(min(self.ylim), max(self.ylim), count=max(3, self.height // 60))
        for value, label in zip(yticks, tick_labels(yticks), strict=True):
            py = round(float(self.to_px(self.xlim[0], value)[1]))
            if grid:
                cv2.line(img, (self.left, py), (right, py), LIGHT, 1)
            cv2.line(img, (self.left - 5, py), (self.left, py), BLACK, 1)
            text(
                img,
                label,
                (self.left - 8, py),
                scale=0.42,
                align="right",
                valign="middle",
            )
        cv2.rectangle(img, (self.left, self.top), (right, bottom), BLACK, 1)
        text(img, xlabel, (self.left + self.width // 2, bottom + 44), scale=0.5, align="centre")
        vertical_text(img, ylabel, (self.left - 62, self.top + self.height // 2), scale=0.5)
        if title:
            text(img, title, (self.left, self.top - 10), scale=0.55, thickness=1)

    def line(
        self,
        x: np.ndarray,
        y: np.ndarray,
        colour: tuple[int, int, int],
        *,
        thickness: int = 1,
        dashed: bool = False,
    ) -> None:
        """Draw a polyline through the finite points, clipped to the box (gaps at NaN)."""
        px, py = self.to_px(x, y)
        finite = np.isfinite(px) & np.isfinite(py)
        px = np.clip(px, self.left, self.left + self.width)
        py = np.clip(py, self.top, self.top + self.height)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
        for start, stop in zip(edges[::2], edges[1::2], strict=True):
            points = np.stack([px[start:stop], py[start:stop]], axis=1)
            points = np.round(points * 16).astype(np.int32).reshape(-1, 1, 2)
            if dashed:
                for k in range(0, len(points) - 1, 2):
                    cv2.line(
                        self.image,
                        tuple(points[k, 0]),
                        tuple(points[k + 1, 0]),
                        colour,
                        thickness,
                        cv2.LINE_AA,
                        shift=4,
                    )
            else:
                cv2.polylines(self.image, [points], False, colour, thickness, cv2.LINE_AA, shift=4)


def dashed_segment(
    axes: Axes,
    x: tuple[float, float],
    y: tuple[float, float],
    colour: tuple[int, int, int],
    *,
    pieces: int = 40,
    thickness: int = 1,
) -> None:
    """Draw a straight dashed line from ``(x[0], y[0])`` to ``(x[1], y[1])`` (data units)."""
    xs = np.linspace(x[0], x[1], 2 * pieces)
    ys = np.linspace(y[0], y[1], 2 * pieces)
    axes.line(xs, ys, colour, thickness=thickness, dashed=True)


def colour_image(
    values: np.ndarray, low: float, high: float, colormap: int = cv2.COLORMAP_VIRIDIS
) -> np.ndarray:
    """Map values in ``[low, high]`` to BGR colours; NaN grey."""
    v = np.asarray(values, dtype=np.float64)
    scaled = np.clip((np.nan_to_num(v, nan=low) - low) / max(high - low, 1e-300), 0, 1)
    image = cv2.applyColorMap((scaled * 255).astype(np.uint8), colormap)
    image[~np.isfinite(v)] = GREY
    return image


def colour_bar(
    image: np.ndarray,
    box: tuple[int, int, int, int],
    low: float,
    high: float,
    *,
    label: str,
    colormap: int = cv2.COLORMAP_VIRIDIS,
) -> None:
    """Draw a vertical colour bar in ``box`` (left, top, width, height) with ticks and a label."""
    left, top, width, height = box
    ramp = np.linspace(high, low, height)[:, None] * np.ones((1, width))
    image[top : top + height, left : left + width] = colour_image(ramp, low, high, colormap)
    cv2.rectangle(image, (left, top), (left + width, top + height), BLACK, 1)
    ticks = nice_ticks(low, high, count=4)
    for value, tick in zip(ticks, tick_labels(ticks), strict=True):
        py = round(top + (high - value) / (high - low) * height) if high > low else top
        cv2.line(image, (left + width, py), (left + width + 4, py), BLACK, 1)
        text(image, tick, (left + width + 7, py), scale=0.4, valign="middle")
    text(image, label, (left, top - 8), scale=0.42)


def legend(
    image: np.ndarray,
    origin: tuple[int, int],
    entries: Sequence[tuple[str, tuple[int, int, int], int]],
    *,
    scale: float = 0.45,
) -> None:
    """Draw legend lines ``(text, colour, thickness)`` downwards from ``origin`` (top-left).

    An entry of thickness 0 is a line of text without a sample (a note on the one above).
    """
    x, y = origin
    for content, colour, thickness in entries:
        if thickness > 0:
            cv2.line(image, (x, y), (x + 26, y), colour, thickness + 1, cv2.LINE_AA)
        text(image, content, (x + 34, y), scale=scale, valign="middle")
        y += 20
