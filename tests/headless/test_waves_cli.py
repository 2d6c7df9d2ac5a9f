"""``holoview waves`` and ``process --maps --waves``: files, figures, values against the truth, and
one-line errors for bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray
from figure_layout import layout_problems, saved_figures
from headless_sim import run_cli

from holoview.headless.waves.analysis import WaveOptions, analyse_waves
from holoview.headless.waves.maps import open_wave_maps
from holoview.optics.wave_fields import DampedMode, PartialWave, PartialWaves

#: The simulated bench of these tests: carriers far apart, few mirror passes.
OPTICS = [
    "--size",
    "256",
    "--pixel-pitch-um",
    "160",
    "--m-r-mrad",
    "0.4",
    "0.025",
    "--m-b-mrad",
    "0.025",
    "0.3",
    "--reflectivity",
    "0.1",
    "--depth-mm",
    "3",
]
TRAVELLING = [
    "--scenario",
    "travelling",
    "--frames",
    "140",
    "--fps",
    "250",
    "--seed",
    "5",
    "--wave-k",
    "250",
    "1500",
    "--wave-components",
    "120",
    "--flow-mm-per-s",
    "20",
    "10",
    "--wave-start-s",
    "0.002",
    "--wave-rise-s",
    "0.01",
    "--no-truth-maps",
]


@pytest.fixture(scope="module")
def travelling(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A recording of travelling waves and its results.h5 with maps (process --maps)."""
    folder = tmp_path_factory.mktemp("waves")
    recording, out = folder / "travelling.h5", folder / "processed"
    assert run_cli_plain(["-q", "simulate", str(recording), *OPTICS, *TRAVELLING]) == 0
    argv = ["-q", "process", str(recording), "--out", str(out), "--maps", "--reference", "absolute"]
    assert run_cli_plain(argv) == 0
    return recording, out / "results.h5"


def run_cli_plain(argv: list[str]) -> int:
    from holoview.cli import main

    return main(argv)


@pytest.mark.slow
def test_waves_writes_spectra_fits_and_figures_close_to_the_truth(
    travelling: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    recording, results = travelling
    out = tmp_path / "waves"
    argv = ["waves", str(results), "--out", str(out), "--segment", "64", "--time", "0.02:"]
    # a 41 mm field holds too few long waves to fix the depth: held at the truth
    status, stdout, err = run_cli([*argv, "--depth-mm", "3", "--hold", "depth"], capsys)
    assert status == 0, err
    assert "sigma" in stdout and "±" in stdout
    with h5py.File(recording, "r") as f:
        truth = dict(f["truth/waves"].attrs)
    summary = json.loads((out / "waves.json").read_text())
    fit = summary["dispersion"]
    assert fit["surface_tension_n_per_m"] == pytest.approx(truth["sigma_n_per_m"], rel=0.05)
    assert fit["surface_tension_stderr_n_per_m"] > 0
    assert fit["depth_m"] == truth["depth_m"] and fit["held"] == ["depth"]
    for axis in (0, 1):
        error = abs(fit["flow_m_per_s"][axis] - truth["flow_m_per_s"][axis])
        assert error < max(3 * fit["flow_stderr_m_per_s"][axis], 2e-3)
    assert "travels along +k" in summary["sign_convention"]
    assert summary["input"]["frames"] == 135 and summary["input"]["gaps"] == 0
    for name in ("waves.h5", "waves.json", "omega_k.png", "energy.png"):
        assert (out / name).is_file()
    assert (out / "omega_k.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with h5py.File(out / "waves.h5", "r") as f:
        assert f.attrs["format"] == "holoview-waves"
        power = f["omega_k/power"]
        assert power.attrs["unit"] == "m^2 Hz^-1 (rad/m)^-2"
        assert [d[0].name for d in power.dims] == [
            "/omega_k/frequency",
            "/omega_k/ky",
            "/omega_k/kx",
        ]

        def has_unit(name: str, item: object) -> None:
            if isinstance(item, h5py.Dataset):
                assert "unit" in item.attrs, name

        f.visititems(has_unit)
        assert f["dispersion"].attrs["surface_tension_n_per_m"] == pytest.approx(
            fit["surface_tension_n_per_m"]
        )
    assert not list(out.glob(".*partial*"))
    for group in ("omega_k", "energy", "dispersion"):  # netCDF-readable: coordinates attached
        with xarray.open_dataset(out / "waves.h5", group=group, engine="h5netcdf") as ds:
            assert all(not name.startswith("phony") for name in ds.sizes)


@pytest.mark.slow
def test_process_maps_waves_in_one_run(
    travelling: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    recording, _ = travelling
    out = tmp_path / "both"
    argv = ["process", str(recording), "--out", str(out), "--maps", "--reference", "absolute"]
    status, stdout, err = run_cli(
        [
            *argv,
            "--waves",
            "--segment",
            "64",
            "--depth-mm",
            "3",
            "--hold",
            "depth",
            "--band-f",
            "10:40",
        ],
        capsys,
    )
    assert status == 0, err
    assert (out / "results.h5").is_file() and (out / "waves.json").is_file()
    assert stdout.count(str(out)) == 2  # one line each
    summary = json.loads((out / "summary.json").read_text())
    assert summary["parameters"]["radius"] == "matched"  # one rule: the default everywhere
    with h5py.File(out / "waves.h5", "r") as f:
        filtered = f["filtered/height"]
        assert filtered.shape[0] == 140 and filtered.attrs["unit"] == "m"
        assert f["filtered"].attrs["f_min"] == 10.0
    status, _, err = run_cli(["process", str(recording), "--out", str(out), "--waves"], capsys)
    assert status == 2 and "--maps" in err
    # a fit setting no fit takes is refused before the run, not after its maps
    again = tmp_path / "again"
    argv = ["process", str(recording), "--out", str(again), "--maps", "--waves", "--hold", "foo"]
    status, _, err = run_cli(argv, capsys)
    assert status == 2 and "cannot hold foo" in err and not again.exists()


def results_file(
    path: Path,
    maps: np.ndarray,
    times: np.ndarray | None,
    pixel: float | None,
    *,
    version: str = "2.0",
) -> Path:
    """A results.h5 with one fused map stack, as process --maps writes it (the parts read).

    Version 2.0: ``units`` and the maps' ``time`` dimension scale; 1.0: ``unit`` and
    ``/trends/time_s``.
    """
    with h5py.File(path, "w") as f:
        dataset = f.create_dataset("maps/fused", data=maps.astype(np.float32))
        unit = "units" if version == "2.0" else "unit"
        dataset.attrs.update({unit: "m", "quantity": "delta_h", "reference": "absolute"})
        if pixel is not None:
            dataset.attrs["pixel_size_m"] = [pixel, pixel]
        if times is not None and version == "2.0":
            f["maps/time"] = times
            f["maps/time"].make_scale("time")
            dataset.dims[0].attach_scale(f["maps/time"])
        elif times is not None:
            f["trends/time_s"] = times
    return path


def field_maps(surface, frames: int, fps: float, size: int, pixel: float, *, noise: float = 0.3e-9):
    x = (np.arange(size) * pixel)[np.newaxis, :]
    y = (np.arange(size) * pixel)[:, np.newaxis]
    rng = np.random.default_rng(0)
    times = np.arange(frames) / fps
    return np.array([surface(t, x, y) + rng.normal(0, noise, (size, size)) for t in times]), times


@pytest.mark.slow
def test_partial_waves_and_ringdown_through_the_command(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    size, pixel, fps = 72, 0.6e-3, 100.0
    centre = (21.5e-3, 20.2e-3)
    waves = (PartialWave(0, 14.3, 20e-9, 12e-9), PartialWave(2, 22.1, 8e-9 + 6e-9j, 15e-9))
    surface = PartialWaves(waves, centre=centre, core_radius=3e-3, depth=5e-3)
    mode = DampedMode(1, 31.0, 1.2, 30e-9, centre=centre, depth=5e-3)
    maps, times = field_maps(
        lambda t, x, y: surface(t, x, y) + mode(t, x, y), 384, fps, size, pixel
    )
    r = np.hypot(
        np.arange(size)[None, :] * pixel - centre[0], np.arange(size)[:, None] * pixel - centre[1]
    )
    maps[:, r < 4e-3] = np.nan
    path = results_file(tmp_path / "results.h5", maps, times, pixel)
    out = tmp_path / "out"
    argv = [
        "waves",
        str(path),
        "--out",
        str(out),
        "--no-fit",
        "--segment",
        "128",
        "--centre",
        "auto",
        "--r-range-mm",
        "5:19",
        "--m-max",
        "4",
        "--n-modes",
        "2",
        "--ringdown",
        "1,28:34",
        "--drive-hz",
        "14.3",
        "--depth-mm",
        "5",
        "--threads",
        "1",  # every figure drawn here, for its layout to be read
    ]
    drawn = saved_figures(monkeypatch)
    status, _, err = run_cli(argv, capsys)
    assert status == 0, err
    assert len(drawn) == 6
    problems = [f"{k}: {p}" for k, figure in enumerate(drawn) for p in layout_problems(figure)]
    assert not problems, "\n".join(problems)
    summary = json.loads((out / "waves.json").read_text())
    found = summary["centre_m"]
    assert np.hypot(found[0] - centre[0], found[1] - centre[1]) < 0.2 * pixel
    assert all(0 <= e < 0.2 * pixel for e in summary["centre_stderr_m"])
    fits = {p["m"]: p for p in summary["partial_waves"]}
    assert set(fits) == {0, 2}
    for wave in waves:
        fit = fits[wave.m]
        assert fit["frequency_hz"] == pytest.approx(wave.frequency, abs=0.01)
        assert fit["incoming_amplitude_m"] == pytest.approx(abs(wave.incoming), rel=0.03)
        assert fit["outgoing_amplitude_m"] == pytest.approx(abs(wave.outgoing), rel=0.03)
        ratio = abs(wave.incoming) / abs(wave.outgoing)
        assert fit["incoming_over_outgoing"] == pytest.approx(ratio, rel=0.03)
    ring = summary["ringdown"]
    assert ring["frequency_hz"] == pytest.approx(31.0, rel=0.005)
    assert ring["decay_per_s"] == pytest.approx(1.2, rel=0.05)
    for name in ("m_f.png", "partial_waves.png", "ringdown.png", "lockin.png"):
        assert (out / name).is_file(), name
    with h5py.File(out / "waves.h5", "r") as f:
        assert f["lockin/amplitude"].shape == (3, size, size)
        assert f["partial_waves/incoming_real_m"].attrs["unit"] == "m"
        for kind in ("incoming", "outgoing"):  # the modulus's error, then the phase's
            json_errors = [fits[m][f"{kind}_phase_stderr_rad"] for m in sorted(fits)]
            rows = dict(
                zip(
                    f["partial_waves/m"][:],
                    f[f"partial_waves/{kind}_phase_stderr_rad"][:],
                    strict=True,
                )
            )
            assert [rows[m] for m in sorted(fits)] == pytest.approx(json_errors)
            assert all(0 < e < 0.1 for e in json_errors)


def test_a_mode_larger_than_the_field_is_centred_beside_a_stronger_uniform_vibration(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """The ringdown simulation's case: a 12 Hz m = 2 mode 18.6 mm long in a 4.8 mm field
    (a saddle there, a few nm), and the reference arm's vibration, a uniform 6.5 Hz
    oscillation stronger than the mode. The spatial taper spreads the vibration over the
    wave vectors next to zero, where E(omega)'s strongest peak had been: the centre was
    sought at 6.5 Hz and the run stopped. Truth: the mode's centre and numbers."""
    size, pixel, fps = 48, 0.1e-3, 200.0
    centre = (2.55e-3, 2.3e-3)
    mode = DampedMode(2, 12.0, 0.8, 60e-9, centre=centre, depth=5e-3)
    maps, times = field_maps(
        lambda t, x, y: mode(t, x, y) + 4e-9 * np.sin(2 * np.pi * 6.5 * t + 0.3),
        400,
        fps,
        size,
        pixel,
    )
    path = results_file(tmp_path / "results.h5", maps, times, pixel)
    out = tmp_path / "out"
    argv = ["waves", str(path), "--out", str(out), "--no-fit", "--segment", "128"]
    status, _, err = run_cli([*argv, "--centre", "auto", "--ringdown", "2,8:16"], capsys)
    assert status == 0, err
    summary = json.loads((out / "waves.json").read_text())
    found = summary["centre_m"]
    assert np.hypot(found[0] - centre[0], found[1] - centre[1]) < 0.2 * pixel
    assert "at 12" in summary["centre_method"]
    ring = summary["ringdown"]
    assert ring["frequency_hz"] == pytest.approx(12.0, rel=0.005)
    assert ring["decay_per_s"] == pytest.approx(0.8, rel=0.05)


def test_a_centre_beyond_where_the_rings_fit_stops_the_run_with_the_radius_that_does(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Rings to 19.4 mm fit around centres from 20.6 mm: the waves' is at y = 20.2 mm.

    Held at the edge of where the rings fit, a centre a pixel off took 2 to 3 % of the
    partial waves' amplitudes (``benchmarks/accuracy_waves.py``, rings to 38 mm).
    """
    size, pixel, fps = 72, 0.6e-3, 100.0
    centre = (21.5e-3, 20.2e-3)
    surface = PartialWaves(
        (PartialWave(0, 14.3, 20e-9, 12e-9),), centre=centre, core_radius=3e-3, depth=5e-3
    )
    maps, times = field_maps(surface, 160, fps, size, pixel)
    path = results_file(tmp_path / "results.h5", maps, times, pixel)
    out = tmp_path / "out"
    argv = ["waves", str(path), "--out", str(out), "--no-fit", "--segment", "128"]
    argv += ["--centre", "auto", "--r-range-mm", "5:19.4", "--drive-hz", "14.3"]
    status, _, err = run_cli(argv, capsys)
    assert status == 2, err
    # the room: 20.2 mm to the nearest edge, less two pixels
    assert "leaves room for rings up to 19.0 mm only" in err or "up to 18.9 mm" in err, err
    assert err.count("\n") == 1 and "Traceback" not in err
    status, _, err = run_cli([*argv[:-4], "--r-range-mm", "5:18.9", "--drive-hz", "14.3"], capsys)
    assert status == 0, err
    found = json.loads((out / "waves.json").read_text())["centre_m"]
    assert np.hypot(found[0] - centre[0], found[1] - centre[1]) < 0.2 * pixel


def test_two_threads_give_the_numbers_of_one(tmp_path: Path) -> None:
    """Threads (omega-k beside the lock-ins, rings sampled in chunks) change no number."""
    size, pixel, fps = 48, 0.6e-3, 100.0
    centre = (14.5e-3, 13.8e-3)
    surface = PartialWaves(
        (PartialWave(0, 14.3, 20e-9, 12e-9),), centre=centre, core_radius=3e-3, depth=5e-3
    )
    maps, times = field_maps(surface, 300, fps, size, pixel)
    maps[:, 20:24, 18:22] = np.nan
    path = results_file(tmp_path / "results.h5", maps, times, pixel)
    found = []
    for workers in (1, 2):
        options = WaveOptions(
            fit=False,
            segment=64,
            centre=centre,
            r_range=(5e-3, 12e-3),
            m_max=3,
            drive=14.3,
            block=40,
            workers=workers,
        )
        with open_wave_maps(path) as wave_maps:
            found.append(analyse_waves(wave_maps, options))
    one, two = found
    assert one.spectrum.segments == two.spectrum.segments > 4
    np.testing.assert_array_equal(one.spectrum.power, two.spectrum.power)
    assert one.lockin is not None and two.lockin is not None
    np.testing.assert_array_equal(one.lockin.amplitude, two.lockin.amplitude)
    assert one.mf is not None and two.mf is not None
    np.testing.assert_array_equal(one.mf.power, two.mf.power)


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("no pixel size", "carry no pixel size"),
        ("no times", "no frame times"),
        ("short", "fewer than a segment"),
        ("all nan", "all NaN"),
        ("centre outside", "outside the maps"),
        ("no label", "has no maps of 'RB7'; it has fused\n"),
        ("hold depth", "--hold depth needs --depth-mm"),
        ("no file", "no such file"),
        # 100 maps/s: above 50 Hz a frequency is another's alias
        ("drive past nyquist", "the drive at 500 Hz is above the maps' Nyquist frequency 50 Hz"),
        ("harmonic past nyquist", "harmonic 3 of the 20 Hz drive at 60 Hz is above"),
        ("mode past nyquist", "the mode m=0 at 70 Hz is above"),
        ("band past nyquist", "the band filter's lowest frequency at 70 Hz is above"),
        ("ringdown past nyquist", "the top of the ringdown's band 40:80 Hz at 80 Hz is above"),
        # a 24 mm field at 1 mm a pixel: the grid's Nyquist wavenumber is pi/1 mm
        ("band past cut-off", "wavenumbers from 5000 rad/m lie past the maps' cut-off 3142"),
        # refused before the spectra are made: the line says nothing of them
        ("hold typo", "cannot hold foo: the parameters are sigma, depth, flow\n"),
        # noise (a surface at rest) has no tone to centre on; before, a centre was found
        ("centre on noise", "no centre can be found: E(omega) has no tone standing 3 times"),
        # the maps' own times would be replaced by even ones, their gap closed
        ("fps over times", "the maps carry their own frame times (maps/time, 1 gap)"),
        # its filter would span 450 frames to pass 10 Hz at one; the maps have 96
        ("band too narrow", "the band 9.5:10.5 Hz is too narrow to filter at 100 maps/s: its"),
        # 100 maps/s, then 77 from frame 200: analysed at 100, its f would be 1.3 times
        ("rate changes", "the frame rate changes: around frame 19"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture, case: str, message: str
) -> None:
    rng = np.random.default_rng(1)
    frames = {"short": 40, "rate changes": 300}.get(case, 96)
    maps = rng.normal(0, 1e-9, (frames, 24, 24))
    if case == "all nan":
        maps[:] = np.nan
    times = np.arange(frames) / 100.0
    if case == "fps over times":
        times[50:] += 0.1  # 10 frames lost
    if case == "rate changes":
        times[200:] = times[200] + 1.3 * (times[200:] - times[200])
    path = results_file(
        tmp_path / "results.h5",
        maps,
        None if case == "no times" else times,
        None if case == "no pixel size" else 1e-3,
    )
    out = tmp_path / "out"
    argv = ["waves", str(path), "--out", str(out), "--segment", "64"]
    extra = {
        "centre outside": ["--centre", "100,5"],
        "no label": ["--label", "RB7"],
        "hold depth": ["--hold", "depth"],
        "drive past nyquist": ["--drive-hz", "500"],
        "harmonic past nyquist": ["--drive-hz", "20"],
        "mode past nyquist": ["--centre", "12,12", "--modes", "0:70"],
        "band past nyquist": ["--band-f", "70:80"],
        "ringdown past nyquist": ["--centre", "12,12", "--ringdown", "0,40:80"],
        "band past cut-off": ["--band-k", "5000:9000"],
        "hold typo": ["--hold", "sigma,foo"],
        "centre on noise": ["--centre", "auto", "--no-fit"],
        "fps over times": ["--fps", "100"],
        "band too narrow": ["--band-f", "9.5:10.5"],
    }.get(case, [])
    if case == "no file":
        argv[1] = str(tmp_path / "missing.h5")
    status, _, err = run_cli([*argv, *extra], capsys)
    assert status == 2
    assert message in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


def test_a_dispersion_fit_that_cannot_be_made_keeps_the_spectra_and_other_analyses(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Maps with no travelling wave (noise, and a standing oscillation at 12 Hz): the fit
    alone asked for is one line and exit 2 after the spectra are written; asked beside a
    lock-in, the lock-in stands and the run succeeds, the reason in waves.json."""
    rng = np.random.default_rng(3)
    times = np.arange(128) / 100.0
    drive = np.cos(2 * np.pi * 12.0 * times)[:, None, None]
    maps = 5e-9 * drive * np.ones((1, 24, 24)) + rng.normal(0, 1e-9, (128, 24, 24))
    path = results_file(tmp_path / "results.h5", maps, times, 1e-3)
    alone = tmp_path / "alone"
    status, out, err = run_cli(["waves", str(path), "--out", str(alone), "--segment", "64"], capsys)
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "no waves there" in err and "--no-fit leaves the fit out" in err, err
    summary = json.loads((alone / "waves.json").read_text())
    assert summary["dispersion"] is None
    assert "no waves there" in summary["dispersion_problem"]
    assert {"omega_k.png", "energy.png", "waves.h5"} <= {p.name for p in alone.iterdir()}
    beside = tmp_path / "beside"
    argv = ["waves", str(path), "--out", str(beside), "--segment", "64", "--drive-hz", "12"]
    status, out, err = run_cli(argv, capsys)
    assert status == 0, err
    assert "no dispersion fit" in out
    summary = json.loads((beside / "waves.json").read_text())
    assert "no waves there" in summary["dispersion_problem"]
    assert any("no dispersion fit" in note for note in summary["notes"])
    assert summary["lockin"]["median_amplitude_m"][0] == pytest.approx(5e-9, rel=0.05)


def test_phase_maps_are_refused_and_a_1_0_file_reads_as_2_0(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    x = np.arange(24)[None, :] * 1e-3
    times = np.arange(128) / 100.0
    maps = np.array([1e-8 * np.cos(800 * x - 2 * np.pi * 20 * t) + 0 * x.T for t in times])
    argv = ["--segment", "64", "--no-fit"]
    summaries = []
    for version in ("2.0", "1.0"):
        path = results_file(tmp_path / f"{version}.h5", maps, times, 1e-3, version=version)
        out = tmp_path / f"out{version}"
        assert run_cli(["waves", str(path), "--out", str(out), *argv], capsys)[0] == 0
        summaries.append(json.loads((out / "waves.json").read_text()))
    assert summaries[0]["omega_k"] == summaries[1]["omega_k"]
    assert summaries[0]["input"]["frames"] == 128
    path = results_file(tmp_path / "phase.h5", maps, times, 1e-3)
    with h5py.File(path, "r+") as f:
        f["maps/fused"].attrs.update({"units": "rad", "quantity": "phase"})
    status, _, err = run_cli(["waves", str(path), "--out", str(tmp_path / "p"), *argv], capsys)
    assert status == 2 and "not heights" in err and err.count("\n") == 1


def test_earlier_outputs_are_kept_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    x = np.arange(24)[None, :] * 1e-3
    times = np.arange(128) / 100.0
    maps = np.array([1e-8 * np.cos(800 * x - 2 * np.pi * 20 * t) + 0 * x.T for t in times])
    path = results_file(tmp_path / "results.h5", maps, times, 1e-3)
    out = tmp_path / "out"
    argv = ["waves", str(path), "--out", str(out), "--segment", "64", "--no-fit"]
    assert run_cli(argv, capsys)[0] == 0
    before = (out / "waves.json").read_bytes()
    status, _, err = run_cli(argv, capsys)
    assert status == 2 and "--overwrite" in err
    assert (out / "waves.json").read_bytes() == before
    assert run_cli([*argv, "--overwrite"], capsys)[0] == 0
    shutil.rmtree(out)


def test_a_fused_map_cut_short_by_one_window_names_the_map_that_reaches_further(
    travelling_waves: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """On the tests' travelling waves RF sits near Nyquist, its own twin 9 bins away: its
    window (4.5 bins) bounds the fused map's band at 695 rad/m, where the waves reach
    1500 rad/m and RB1's window passes them. The default (fused) map has too few cells for
    the dispersion fit; the one line says which map reaches further."""
    out = tmp_path / "processed"
    status, _, err = run_cli(
        ["process", str(travelling_waves), "--out", str(out), "--maps"], capsys
    )
    assert status == 0, err
    status, _, err = run_cli(
        ["waves", str(out / "results.h5"), "--out", str(tmp_path / "w")], capsys
    )
    assert status == 2
    assert len(err.strip().splitlines()) == 1, err
    assert "maps/fused pass waves up to" in err and "try holoview waves --label RB1" in err, err
    argv = ["waves", str(out / "results.h5"), "--out", str(tmp_path / "rb1"), "--label", "RB1"]
    status, out, err = run_cli([*argv, "--depth-mm", "1", "--hold", "depth"], capsys)
    assert status == 0, err
    # a held depth is said to be held, not written "1 ± 0"; the others with their errors
    assert "depth 1 mm (held)" in out and "mN/m" in out and " ± " in out, out


@pytest.mark.parametrize("command", ["waves", "export"])
def test_a_truncated_results_file_is_said_to_be_truncated(
    tmp_path: Path, capsys: pytest.CaptureFixture, command: str
) -> None:
    """An interrupted copy of results.h5: named as such, as process and peaks name a
    recording's (it was HDF5's own 'truncated file: eof = ...' line)."""
    rng = np.random.default_rng(1)
    maps = rng.normal(0, 1e-9, (96, 24, 24))
    whole = results_file(tmp_path / "results.h5", maps, np.arange(96) / 100.0, 1e-3)
    cut = tmp_path / "cut.h5"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 3])
    out = tmp_path / "out"
    extra = ["--to", "netcdf"] if command == "export" else []
    status, _, err = run_cli([command, str(cut), "--out", str(out), *extra], capsys)
    assert status == 2
    assert f"{cut}: truncated: the file has" in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_the_api_takes_a_pair_as_a_pair(tmp_path: Path) -> None:
    """``holoview.api.waves(..., centre=(x, y))`` as ``--centre x,y`` (it was split into two
    arguments: 'unrecognized arguments'); options of two values still take a tuple."""
    import holoview.api as hv
    from holoview.errors import InputError

    rng = np.random.default_rng(2)
    maps = rng.normal(0, 1e-9, (96, 24, 24))
    path = results_file(tmp_path / "results.h5", maps, np.arange(96) / 100.0, 1e-3)
    outcome = hv.waves(path, tmp_path / "w", centre=(12, 11), no_fit=True, segment=64)
    assert outcome.summary["centre_m"] == pytest.approx([0.012, 0.011])
    with pytest.raises(InputError, match=r"the centre \(99, 11\) mm is outside the maps"):
        hv.waves(path, tmp_path / "w2", centre=(99, 11), no_fit=True, segment=64)
    made = hv.simulate(tmp_path / "s.h5", "evaporation", size=32, frames=2, m_r_mrad=(0.5, 0.3))
    with h5py.File(made, "r") as f:
        assert f["setup"].attrs["m_r_rad"] == pytest.approx([0.5e-3, 0.3e-3])
