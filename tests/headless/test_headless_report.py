"""The report of ``holoview process``: a matplotlib figure in PNG, PDF or SVG, no Qt, no X.

The SVG keeps its text as text, so what the figure says is read back: the peaks'
labels on the spectrum, each rate with its standard error as ``summary.json`` has it.
"""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from figure_layout import layout_problems, saved_figures
from headless_sim import Simulated, run_cli

from holoview.processing.series.rate_fits import format_rate

SVG = "{http://www.w3.org/2000/svg}"


def svg_texts(path: Path) -> list[str]:
    """Every text of an SVG figure, in drawing order."""
    root = ET.parse(path).getroot()
    return ["".join(node.itertext()) for node in root.iter(f"{SVG}text")]


def test_report_png_is_1366_pixels_wide_and_drawn(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r"
    argv = ["process", str(evaporation.path), "--out", str(out), "--frames", ":30"]
    status, _, _ = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 0
    image = cv2.imread(str(out / "report.png"))
    assert image is not None and image.shape[1] == 1366 and image.shape[0] > 900
    # the spectrum, curves and maps put colour on the page
    assert np.mean(image < 250) > 0.1
    assert sorted(p.name for p in out.iterdir()) == [
        "report.png",
        "results.h5",
        "summary.json",
        "trends.csv",
    ]


def test_every_text_of_the_report_lies_on_the_page(
    evaporation: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The spectrum panel's title had run off the figure's left edge ("...es: each peak's
    window"): every text drawn must lie within the page, no tick labels overlapping."""
    drawn = saved_figures(monkeypatch)
    out = tmp_path / "r"
    argv = ["process", str(evaporation.path), "--out", str(out), "--frames", ":30"]
    status, _, _ = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 0 and len(drawn) == 1
    assert layout_problems(drawn[0]) == []


def test_the_report_draws_each_map_pixel_where_results_h5_puts_it(
    evaporation: Simulated,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Map pixel (r, c) at (x[c], y[r]) of results.h5: the maps were drawn from the
    frame's edges, half a map pixel (2.7 frame pixels at 256^2) down and right."""
    drawn = saved_figures(monkeypatch)
    out = tmp_path / "r"
    argv = ["process", str(evaporation.path), "--out", str(out), "--frames", ":30", "--maps"]
    status, _, _ = run_cli([*argv, *evaporation.label_args("RB1", "FB1")], capsys)
    assert status == 0 and len(drawn) == 1
    with h5py.File(out / "results.h5", "r") as f:
        x, y = f["maps/x"][:] * 1e3, f["maps/y"][:] * 1e3  # mm, as the report
    maps = [im for ax in drawn[0].axes for im in ax.get_images() if im.get_array().ndim == 2]
    maps = [im for im in maps if im.get_array().shape == (y.size, x.size)]
    assert maps
    for image in maps:
        left, right, bottom, top = image.get_extent()
        step_x, step_y = (right - left) / x.size, (bottom - top) / y.size
        assert left + step_x / 2 == pytest.approx(x[0], abs=1e-9)
        assert right - step_x / 2 == pytest.approx(x[-1], rel=1e-9)
        assert top + step_y / 2 == pytest.approx(y[0], abs=1e-9)
        assert bottom - step_y / 2 == pytest.approx(y[-1], rel=1e-9)


def test_report_svg_says_the_labels_and_rates_of_the_summary(
    waves: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r"
    argv = ["process", str(waves.path), "--out", str(out), "--maps", "--report-format", "svg"]
    status, _, _ = run_cli([*argv, *waves.label_args("RB1", "FB1")], capsys)
    assert status == 0
    assert not (out / "report.png").exists()
    texts = svg_texts(out / "report.svg")
    summary = json.loads((out / "summary.json").read_text())
    labels = list(summary["peaks"])
    assert {"RB1", "FB1", "RF"} <= set(labels)
    for label, peak in summary["peaks"].items():
        assert label in texts  # on the spectrum
        rate = format_rate(peak["rate_m_per_s"], peak["rate_stderr_m_per_s"])
        assert any(t.startswith(f"{label} (") and t.endswith(rate) for t in texts), rate
    fused = summary["fused"]
    fused_rate = format_rate(fused["rate_m_per_s"], fused["rate_stderr_m_per_s"])
    assert f"fused: {fused_rate}" in texts
    assert "\u00b1" in fused_rate and fused_rate.endswith("\u00b5m/min")
    # the maps' axes in mm on the object side, the fused map titled
    assert "x (mm)" in texts and any(t.startswith("fused") for t in texts)
    assert "\u0394h (nm)" in texts


def test_report_pdf_replaces_an_earlier_png_only_with_overwrite(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r"
    argv = ["process", str(evaporation.path), "--out", str(out), "--frames", ":10"]
    argv += evaporation.label_args("RB1", "FB1")
    assert run_cli(argv, capsys)[0] == 0
    status, _, err = run_cli([*argv, "--report-format", "pdf"], capsys)
    assert status == 2 and "report.png" in err  # an earlier run's report counts
    status, _, _ = run_cli([*argv, "--report-format", "pdf", "--overwrite"], capsys)
    assert status == 0
    assert not (out / "report.png").exists()  # the folder never mixes two runs
    pdf = (out / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF-") and b"/FontFile2" in pdf  # TrueType text, not outlines


def test_figures_load_neither_qt_nor_x_libraries(evaporation: Simulated, tmp_path: Path) -> None:
    """``simulate --png`` and ``process``'s report in a fresh interpreter: no Qt, no X.

    No Qt module, no GUI backend of matplotlib, and no X, OpenGL or D-Bus library of
    the system (what the apt packages bring; a wheel's own copies are fine).
    """
    code = f"""
import json, sys
from holoview.cli import main
assert main(["-q", "simulate", {str(tmp_path / "s.h5")!r}, "--size", "64", "--frames", "2",
             "--png", {str(tmp_path / "s.png")!r}]) == 0
assert main(["-q", "process", {str(evaporation.path)!r}, "--out", {str(tmp_path / "r")!r},
             "--frames", ":5", "--report-format", "svg"]) == 0
qt = sorted(m for m in sys.modules if m.split(".")[0] in ("PyQt6", "PyQt5", "PySide6", "pyqtgraph"))
backends = sorted(m for m in sys.modules if m.startswith("matplotlib.backends.backend_"))
with open("/proc/self/maps") as maps:
    libraries = {{line.split()[-1] for line in maps if ".so" in line}}
# wheels may bundle their own (Pillow's libxcb): only the system's would need apt
x = sorted(
    p for p in libraries
    if p.rsplit("/", 1)[-1].startswith(("libX", "libxcb", "libGL", "libEGL", "libxkb", "libdbus"))
    and not p.startswith(sys.prefix)
)
print(json.dumps([qt, backends, x]))
"""
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert result.returncode == 0, result.stderr
    qt, backends, x = json.loads(result.stdout.strip().splitlines()[-1])
    assert qt == []
    assert "matplotlib.backends.backend_agg" in backends
    assert not any(kind in b for b in backends for kind in ("qt", "tk", "gtk", "wx", "macosx"))
    assert x == []
    assert (tmp_path / "s.png").stat().st_size > 10_000
    assert (tmp_path / "r" / "report.svg").is_file()
