"""``holoview simulate``: a recording with its truth, a figure, one-line errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest

from holoview.acquire.recording_reader import RecordingReader
from holoview.cli import main
from holoview.optics.families import predict_families
from holoview.optics.scenarios import ScenarioConfig, make_surface, simulate
from holoview.optics.setup import Setup


def test_waves_recording_with_truth_and_figure(tmp_path: Path) -> None:
    out, png = tmp_path / "waves.h5", tmp_path / "waves.png"
    options = ["--size", "64", "--frames", "4", "--fps", "20", "--seed", "3"]
    figure = ["--png", str(png), "--png-frame", "2", "--fluid", "isopropanol"]
    status = main(["-q", "simulate", str(out), *options, *figure])
    assert status == 0
    setup = Setup(shape=(64, 64), n2=1.377)
    surface = make_surface(setup, "waves", ScenarioConfig(), np.random.default_rng(3))
    expected = list(simulate(setup, "waves", frames=4, fps=20.0, seed=3, surface=surface))
    with RecordingReader(out) as reader:
        assert len(reader) == 4
        np.testing.assert_array_equal(reader[:], np.array([f for f, _ in expected]))
        assert reader.setup["n2"] == pytest.approx(1.377)
        assert reader.setup["wavelength_m"] == pytest.approx(setup.wavelength)
        assert reader.source == "simulate:waves"
    with h5py.File(out, "r") as f:
        truth = f["truth"]
        assert truth.attrs["scenario"] == "waves"
        # a waves scenario lets nothing evaporate: its truth lists no rate it does not apply
        assert "evaporation_rate_m_per_s" not in truth.attrs
        assert "injection_rate_m3_per_s" not in truth.attrs
        np.testing.assert_allclose(truth["time_s"][:], np.arange(4) / 20.0)
        np.testing.assert_allclose(truth["height_m"][2], expected[2][1].height, rtol=1e-6)
        np.testing.assert_allclose(truth["mean_height_m"][:], [t.mean_height for _, t in expected])
        labels = [s.decode() for s in truth["families/label"][:]]
        families = {f.label: f for f in predict_families(setup, max_order=4)}
        assert labels == [f.label for f in predict_families(setup, max_order=4)]
        row = labels.index("RB1")
        np.testing.assert_allclose(truth["families/carrier_cpp"][row], families["RB1"].carrier)
        assert truth["families/alpha"][row] == pytest.approx(1.377 - setup.n1)
    image = cv2.imread(str(png))
    assert image is not None and image.shape[1] == 1366 and image.shape[0] == 640


def test_uniform_scenarios_have_no_height_maps(tmp_path: Path) -> None:
    out = tmp_path / "evap.h5"
    args = ["-q", "simulate", str(out), "--scenario", "evaporation", "--size", "32"]
    assert main([*args, "--frames", "3", "--evaporation-um-per-min", "6"]) == 0
    with h5py.File(out, "r") as f:
        assert "height_m" not in f["truth"]
        assert f["truth"].attrs["evaporation_rate_m_per_s"] == pytest.approx(1e-7)
        heights = f["truth/mean_height_m"][:]
        times = f["truth/time_s"][:]
    np.testing.assert_allclose(heights, -6e-6 / 60 * times, atol=1e-18)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--wavelength-nm", "nan"], "wavelength"),
        (["--wavelength-nm", "-532"], "wavelength"),
        (["--m-r-mrad", "8", "0"], "m_r"),
        (["--n2", "0.9"], "n2"),
        (["--frames", "0"], "--frames"),
        (["--ghost", "sample", "1", "0", "0.1"], "ghost"),
        (["--png-frame", "60"], "--png-frame"),
        (
            ["--scenario", "partial-waves", "--partial-wave", "0", "14", "abc", "12"],
            "--partial-wave 0 14 abc 12: 'abc' is not IN_NM, an amplitude in nm such as 8",
        ),
        (
            ["--scenario", "partial-waves", "--partial-wave", "x", "14", "8", "12"],
            "'x' is not M, a whole number",
        ),
    ],
)
def test_bad_input_is_one_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], message: str
) -> None:
    out = tmp_path / "bad.h5"
    status = main(["simulate", str(out), "--size", "16", "--png", str(tmp_path / "x.png"), *args])
    assert status == 2
    error = capsys.readouterr().err
    assert message in error
    assert len(error.strip().splitlines()) == 1, error
    assert not out.exists()


def test_existing_recording_is_not_overwritten(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "x.h5"
    out.write_bytes(b"keep")
    assert main(["simulate", str(out), "--size", "16", "--frames", "1"]) == 2
    assert "exists" in capsys.readouterr().err
    assert out.read_bytes() == b"keep"


@pytest.mark.parametrize(
    ("scenario", "pitch_um", "warned"),
    [
        ("partial-waves", "20", "within 1.5 core radii"),  # a 2.6 mm field, a 4 mm core
        ("ringdown", "20", "wavelength of 18.7 mm"),  # the 12 Hz mode in a 2.6 mm field
        ("travelling", "20", "below the first wavenumber"),  # 1.8 mm waves, 2.6 mm field
        ("partial-waves", "320", None),  # 41 mm: rings around the core
        ("ringdown", "320", None),
        ("travelling", "320", None),  # waves to 1800 rad/m, fitted from 613 (41 mm)
    ],
)
def test_a_field_too_small_for_the_waves_is_warned_of(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, scenario: str, pitch_um: str, warned: str
) -> None:
    argv = ["simulate", str(tmp_path / "w.h5"), "--scenario", scenario, "--size", "128"]
    tilts = ["--m-r-mrad", "0.4", "0.025", "--m-b-mrad", "0.025", "0.3"]  # carriers for 320 um
    with caplog.at_level("WARNING", logger="holoview.cli.simulate_waves"):
        frames = ["--frames", "2", "--fps", "300"]  # the travelling waves reach 111 Hz
        assert main([*argv, *tilts, *frames, "--pixel-pitch-um", pitch_um]) == 0
    said = [r.getMessage() for r in caplog.records if r.name == "holoview.cli.simulate_waves"]
    if warned is None:
        assert said == []
    else:
        assert len(said) == 1 and warned in said[0] and "--pixel-pitch-um" in said[0], said


def test_a_pixel_pitch_given_alone_keeps_the_carriers_where_they_were(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The default tilts suit 20 um: at 320 um (the wave scenarios' field of centimetres,
    what their warning asks for) RB1 lay past Nyquist and simulate refused. A pitch given
    without tilts scales them; the carriers keep their place in cycles/pixel."""
    common = ["--scenario", "travelling", "--size", "64", "--frames", "2", "--fps", "300"]
    paths = {pitch: tmp_path / f"p{pitch}.h5" for pitch in ("20", "320")}
    with caplog.at_level("WARNING", logger="holoview.cli.simulate_waves"):
        for pitch, path in paths.items():
            assert main(["-q", "simulate", str(path), *common, "--pixel-pitch-um", pitch]) == 0
    carriers = {}
    for pitch, path in paths.items():
        with h5py.File(path, "r") as f:
            labels = [s.decode() for s in f["truth/families/label"][:]]
            cpp = f["truth/families/carrier_cpp"][:]
            carriers[pitch] = {name: cpp[labels.index(name)] for name in ("RF", "RB1", "FB1")}
    for name in ("RF", "RB1", "FB1"):
        np.testing.assert_allclose(carriers["320"][name], carriers["20"][name], rtol=1e-9)
    # the waves (to 1800 rad/m: 0.09 cycles/pixel at 320 um) now spread the holograms,
    # 0.16 cycles/pixel apart, into one another: said, with the options that spread them
    said = [r.getMessage() for r in caplog.records if "bands overlap" in r.getMessage()]
    assert len(said) == 1 and "320 um" in said[0] and "--m-r-mrad" in said[0], said
