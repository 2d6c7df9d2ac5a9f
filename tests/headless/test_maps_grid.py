"""``process --maps --maps-grid frame``: every map on the camera frame's pixels (issue 23).

Checked against numbers the run did not compute: a plain numpy Fourier filter of the
recording's frames written here (the frame's FFT, a disc of the run's radius at each
peak's carrier, moved to zero frequency, inverted at the frame's size, the phase
against the first frame's, converted with the map's own alpha and the wavelength),
the simulator's true surface, and the same run's box maps at the pixels both grids
share (read through the coordinates xarray gives).
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr
from headless_sim import run_cli

from holoview.api import open_results, process
from holoview.cli import main
from holoview.errors import InputError

SIZE = 128
FRAMES = 6
#: A top-hat disc whose box is 16 x 16 at 128 x 128: box pixel p is frame pixel 8 p.
RADIUS = 0.052
LABELS = ("RB1", "RF", "FB1", "RB2")
#: The lowest correlation with the true surface's change, per frame (RF's sideband is
#: six times weaker than RB1's; the change from the first frame is 4-10 nm rms).
LOWEST = {"RB1": 0.96, "RF": 0.85}


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Standing waves of 40 nm rms on water, 128 x 128, six frames, with the true surface."""
    path = tmp_path_factory.mktemp("sim") / "waves.h5"
    argv = ["-q", "simulate", str(path), "--scenario", "waves", "--size", str(SIZE)]
    argv += ["--frames", str(FRAMES), "--fps", "20", "--seed", "3", "--wave-rms-nm", "40"]
    assert main(argv) == 0
    return path


def _carriers(path: Path) -> dict[str, tuple[float, float]]:
    with h5py.File(path, "r") as f:
        families = f["truth"]["families"]
        labels = [s.decode() for s in families["label"][:]]
        carriers = families["observed_carrier_cpp"][:]
    return {k: (float(c[0]), float(c[1])) for k, c in zip(labels, carriers, strict=True)}


@pytest.fixture(scope="module")
def runs(recording: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same absolute top-hat run on the box's grid and on the frame's: results.h5 of each."""
    carriers = _carriers(recording)
    folder = tmp_path_factory.mktemp("grids")
    done = {}
    for grid in ("box", "frame"):
        outcome = process(
            recording,
            folder / grid,
            labels={k: carriers[k] for k in LABELS},
            reference="absolute",
            window="top-hat",
            radius=RADIUS,
            maps=True,
            maps_grid=grid,
            jobs=1,
            report=False,
        )
        assert outcome.summary["parameters"]["maps_grid"] == grid
        done[grid] = outcome.out / "results.h5"
    return done


def _fourier_filter(frame: np.ndarray, carrier: tuple[float, float]) -> np.ndarray:
    rows, cols = frame.shape
    spectrum = np.fft.fft2(frame.astype(np.float64))
    fy = np.fft.fftfreq(rows)[:, None]
    fx = np.fft.fftfreq(cols)[None, :]
    disc = np.hypot(fx - carrier[0], fy - carrier[1]) <= RADIUS
    k0y, k0x = round(carrier[1] * rows), round(carrier[0] * cols)
    return np.fft.ifft2(np.roll(spectrum * disc, (-k0y, -k0x), axis=(0, 1)))


def test_frame_grid_maps_are_a_plain_fourier_filters_and_follow_the_truth(
    recording: Path, runs: dict[str, Path]
) -> None:
    with h5py.File(recording, "r") as f:
        frames = f["frames"][:]
        pitch = float(f["setup"].attrs["pixel_pitch_m"])
        truth = f["truth"]["height_m"][:]
    with h5py.File(runs["frame"], "r") as f:
        wavelength = float(f.attrs["wavelength_m"])
    maps = open_results(runs["frame"], "maps")
    try:
        assert maps.sizes == {"time": FRAMES, "y": SIZE, "x": SIZE}
        np.testing.assert_allclose(maps.y, np.arange(SIZE) * pitch)
        np.testing.assert_allclose(maps.x, np.arange(SIZE) * pitch)
        assert maps.x.attrs["units"] == "m" and maps.y.attrs["units"] == "m"
        inner = (slice(12, -12), slice(12, -12))
        for label in LABELS:
            m = maps[label]
            assert m.attrs["grid"] == "frame" and list(m.attrs["pixel_step_px"]) == [1, 1]
            carrier = tuple(float(v) for v in m.attrs["carrier_cpp"])
            to_height = wavelength / (4 * np.pi * float(m.attrs["alpha"]))
            reference = _fourier_filter(frames[0], carrier)
            for k in range(1, FRAMES):
                measured = m.isel(time=k).values
                trusted = np.isfinite(measured)
                # the untrusted border (0.4 / radius = 7.7 pixels), trusted within
                assert not trusted[:7].any() and not trusted[:, -7:].any(), label
                assert trusted[inner].mean() > 0.95, label
                expected = np.angle(_fourier_filter(frames[k], carrier) * np.conj(reference))
                wrapped = np.angle(np.exp(1j * (measured / to_height - expected)))
                assert np.abs(wrapped[trusted]).max() < 2e-3, f"{label}, frame {k}"
                # and the surface itself, on the same pixels, for the peaks that see
                # it where the camera does (the simulator's displacements of RB1 and RF
                # are below a pixel; FB1's and RB2's patches lie tens of pixels away)
                if label in LOWEST:
                    change = (truth[k] - truth[0])[trusted]
                    r = np.corrcoef(change, measured[trusted])[0, 1]
                    assert r > LOWEST[label], f"{label}, frame {k}: r = {r:.3f}"
        fused = maps.fused.isel(time=FRAMES - 1).values
        keep = np.isfinite(fused)
        change = (truth[-1] - truth[0])[keep]
        assert np.corrcoef(change, fused[keep])[0, 1] > 0.95
        # up to the level, which the reference arm's path moves too
        error = fused[keep] - change
        assert np.std(error) < 0.3 * np.std(change)
    finally:
        maps.close()


def test_box_maps_are_the_frame_grids_at_the_pixels_they_share(runs: dict[str, Path]) -> None:
    with (
        xr.open_dataset(runs["box"], group="maps", engine="h5netcdf") as box,
        xr.open_dataset(runs["frame"], group="maps", engine="h5netcdf") as frame,
    ):
        assert box.sizes["y"] == SIZE // 8 and box.fused.attrs["grid"] == "box"
        for label in [*LABELS, "fused"]:
            coarse = box[label].isel(time=slice(1, None))
            fine = frame[label].isel(time=slice(1, None)).sel(y=box.y, x=box.x)
            assert (fine.y.values == box.y.values).all()
            a, b = coarse.values, fine.values
            both = np.isfinite(a) & np.isfinite(b)
            assert both.mean() > 0.5, label
            if label == "fused":
                # the maps moved onto RB1's grid by cubic convolution on each grid (on
                # 16 x 16 maps of waves 20 to 60 pixels long, FB1's and RB2's shifts of
                # several box pixels), which blanks what an untrusted pixel reaches:
                # alike, not equal (0.93 to 0.998 on these frames)
                for k in range(len(a)):
                    ok = both[k]
                    assert np.corrcoef(a[k][ok], b[k][ok])[0, 1] > 0.9, f"fused, frame {k + 1}"
            else:
                # the same trusted pixels, the same heights (float32 FFTs of other sizes)
                assert (np.isfinite(a) != np.isfinite(b)).mean() < 0.01, label
                assert np.abs(a[both] - b[both]).max() < 1e-3 * np.abs(a[both]).max(), label
        # the displacements: measured on box maps, given in each grid's pixels
        for label in LABELS[1:]:
            step = np.asarray(box[label].attrs["pixel_step_px"])
            np.testing.assert_allclose(
                frame[label].attrs["displacement_px"],
                np.asarray(box[label].attrs["displacement_px"]) * step,
                rtol=1e-12,
            )


def test_maps_grid_without_maps_is_one_line_and_exit_2(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = ["process", str(recording), "--out", str(tmp_path / "o"), "--maps-grid", "frame"]
    status, _, err = run_cli(argv, capsys)
    assert status == 2
    assert err.strip().splitlines() == [
        "holoview process: error: --maps-grid frame places the maps: give --maps too"
    ]
    with pytest.raises(InputError, match="unknown --maps-grid 'pixels'; choose one of box, frame"):
        process(recording, tmp_path / "p", maps=True, maps_grid="pixels", report=False)
