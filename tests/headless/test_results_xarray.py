"""results.h5 format 2.1 opened by xarray itself: dimensions, coordinates in s and m, units.

The coordinates are checked against numbers the writer did not compute: the
simulator's true frame times and true height maps (whose pixel (i, j) sits at
(i, j) pixel pitches), and the recording's pixel pitch. Format 1.0, written by the
writer of holoview 0.1.0 before this change (``data/results_v1.h5``: ``holoview
simulate rec.h5 --scenario evaporation --size 64 --frames 8 --fps 20 --seed 5
--evaporation-um-per-min 60`` then ``holoview process rec.h5 --out out --maps --jobs 1
--area 0.01`` at commit fea880d), still opens into the same Datasets, and so does format
2.0 (``data/results_v2_0.h5``, booleans and complex numbers in h5py's HDF5 enum and
compound types: ``holoview simulate rec.h5 --scenario waves --size 64 --frames 8 --fps
20 --seed 5 --wave-rms-nm 40`` then ``holoview process rec.h5 --out out --maps --jobs 1
--area 0.01`` at commit 8e2a7cb). Debian 12's ncdump (netCDF-C 4.9.0, which drops
those types without a word) is run on results.h5 where it is installed.
"""

from __future__ import annotations

import csv
import re
import shutil
import subprocess
from pathlib import Path

import h5py
import netCDF4
import numpy as np
import pytest
import tifffile
import xarray as xr
from headless_sim import Simulated, run_cli

from holoview.errors import InputError
from holoview.headless.results.exports import export_results
from holoview.headless.results.results_data import map_labels, open_results, results_version
from holoview.headless.results.results_layout import RESULTS_VERSION

V1_FILE = Path(__file__).parent / "data" / "results_v1.h5"
V2_0_FILE = Path(__file__).parent / "data" / "results_v2_0.h5"


@pytest.fixture(scope="module")
def wave_maps(waves: Simulated, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Absolute maps of the standing waves, frames 0 to 39: an output folder."""
    from holoview.cli import main

    out = tmp_path_factory.mktemp("xr") / "maps"
    argv = ["-q", "process", str(waves.path), "--out", str(out), "--maps", "--jobs", "1"]
    assert main([*argv, "--reference", "absolute", "--frames", "0:40", "--area", "0.01"]) == 0
    return out


def numeric(variable: xr.DataArray) -> bool:
    return variable.dtype.kind in "fciub"


def test_maps_open_as_h_of_time_y_x_in_seconds_and_metres(
    waves: Simulated, wave_maps: Path
) -> None:
    path = wave_maps / "results.h5"
    with h5py.File(waves.path, "r") as f:
        pitch = float(f["setup"].attrs["pixel_pitch_m"])
    with xr.open_dataset(path, group="maps", engine="h5netcdf") as maps:
        assert not any(str(d).startswith("phony_dim") for d in maps.dims)
        assert set(maps.dims) == {"time", "y", "x"}
        labels = map_labels(maps)
        assert {"RB1", "RF", "FB1", "fused"} <= set(labels)
        for label in labels:
            assert maps[label].dims == ("time", "y", "x")
            assert maps[label].attrs["units"] == "m"
        assert maps.time.attrs["units"] == "s"
        assert maps.y.attrs["units"] == "m" and maps.x.attrs["units"] == "m"
        np.testing.assert_allclose(maps.time, waves.time_s[:40] - waves.time_s[0], atol=1e-9)
        np.testing.assert_array_equal(maps.frame, np.arange(40))
        # map pixel p is centred on frame pixel p * frame/box, frame pixel i at i pitches
        step = 128 / maps.sizes["y"]
        np.testing.assert_allclose(maps.y, np.arange(maps.sizes["y"]) * step * pitch)
        np.testing.assert_allclose(maps.x, np.arange(maps.sizes["x"]) * step * pitch)
        # the fused map at (y, x) follows the true surface at the same place
        assert waves.height_maps is not None
        truth = xr.DataArray(
            waves.height_maps[:40] - waves.height_maps[0],
            dims=("time", "y", "x"),
            coords={"y": np.arange(128) * pitch, "x": np.arange(128) * pitch},
        )
        inner = {"y": slice(3, -3), "x": slice(3, -3)}  # the FFT's wrap-around at the edges
        for k in (20, 39):
            measured = maps.fused.isel(time=k).isel(inner)
            expected = truth.isel(time=k).sel(y=measured.y, x=measured.x, method="nearest")
            keep = np.isfinite(measured.values)
            assert keep.mean() > 0.9
            r = np.corrcoef(expected.values[keep], measured.values[keep])[0, 1]
            assert r > 0.9


def test_every_numeric_variable_has_units_and_no_dimension_is_phony(wave_maps: Path) -> None:
    path = wave_maps / "results.h5"
    for group in ("maps", "trends", "peaks"):
        with xr.open_dataset(path, group=group, engine="h5netcdf") as ds:
            assert not any(str(d).startswith("phony_dim") for d in ds.dims), group
            for name, variable in ds.variables.items():
                if numeric(variable):
                    assert variable.attrs.get("units"), (group, name)
                    assert "unit" not in variable.attrs, (group, name)
                assert variable.attrs.get("long_name"), (group, name)
    with h5py.File(path, "r") as f:
        assert f.attrs["format_version"] == RESULTS_VERSION
        assert f.attrs["Conventions"] == "CF-1.11"


def test_trends_by_time_and_label_agree_with_trends_csv(wave_maps: Path) -> None:
    with xr.open_dataset(wave_maps / "results.h5", group="trends", engine="h5netcdf") as trends:
        assert trends.mean_height_m.dims == ("time", "label")
        assert trends.carrier_value_real.dims == trends.carrier_value_imag.dims == ("time", "label")
        assert trends.fused_height_m.dims == ("time",)
        assert trends.fused_volume_m3.attrs["units"] == "m3"
        assert "frame" in trends.coords
        with open(wave_maps / "trends.csv", newline="") as f:
            rows = [r for r in csv.DictReader(f) if r["label"] != "fused"]
        for row in rows[:: len(trends.label)]:
            value = trends.mean_height_m.sel(label=row["label"]).sel(frame=int(row["frame"]))
            assert float(value) == pytest.approx(float(row["mean_height_m"]), rel=1e-8)
            assert float(value.time) == pytest.approx(float(row["time_s"]), abs=1e-9)
    with xr.open_dataset(wave_maps / "results.h5", group="peaks", engine="h5netcdf") as peaks:
        assert peaks.carrier_cpp.dims == ("label", "component")
        assert list(peaks.component.values) == ["fx", "fy"]
        assert peaks.rate_m_per_s.attrs["units"] == "m s-1"


def test_netcdf_c_reads_results_h5_itself(wave_maps: Path) -> None:
    """The netCDF-C library (through netCDF4) opens results.h5 with named dimensions."""
    with netCDF4.Dataset(wave_maps / "results.h5") as nc:
        fused = nc["maps"]["fused"]
        assert fused.dimensions == ("time", "y", "x")
        assert fused.units == "m"
        assert nc["trends"]["mean_height_m"].dimensions == ("time", "label")
        for group in ("maps", "trends"):  # seconds from the first frame, not a date:
            time = nc[group]["time"]  # CF 4.4 wants "since" a date of a T axis
            assert time.units == "s" and "axis" not in time.ncattrs()
            assert "standard_name" not in time.ncattrs()


def test_debian_ncdump_reads_every_item_of_results_h5(wave_maps: Path) -> None:
    """netCDF-C before 4.10 (Debian 12's ncdump, 4.9.0) drops HDF5 enum and compound types
    without a word: results.h5 2.0's booleans and complex carrier value. The system's
    ncdump shows every one of them in 2.1: the attributes ``interrupted`` and
    ``displacement_measured``, the variables ``ambiguity_flagged``, ``used_in_fused``
    and the carrier value's two parts, with their values."""
    ncdump = shutil.which("ncdump")
    if ncdump is None:
        pytest.skip("no ncdump here (netCDF-C's tool; on Debian: apt-get install netcdf-bin)")

    def dump(*options: str) -> str:
        argv = [ncdump, *options, str(wave_maps / "results.h5")]
        return subprocess.run(argv, capture_output=True, text=True, check=True).stdout

    header = dump("-h")
    assert "\t\t:interrupted = 0b ;" in header
    with open_results(wave_maps, "maps") as maps:
        measured = {
            label: maps[label].attrs["displacement_measured"]
            for label in map_labels(maps)
            if label != "fused"
        }
    for label, value in measured.items():
        assert f"{label}:displacement_measured = {int(value)}b ;" in header, label
    for declaration in (
        "byte ambiguity_flagged(time) ;",
        "byte used_in_fused(label) ;",
        "float carrier_value_real(time, label) ;",
        "float carrier_value_imag(time, label) ;",
    ):
        assert declaration in header
    with open_results(wave_maps, "trends") as trends, open_results(wave_maps, "peaks") as peaks:
        expected = {
            "/trends/ambiguity_flagged": trends.ambiguity_flagged.values,
            "/peaks/used_in_fused": peaks.used_in_fused.values,
            "/trends/carrier_value_real": trends.carrier_value.values.real,
            "/trends/carrier_value_imag": trends.carrier_value.values.imag,
        }
    for name, values in expected.items():
        short = name.rsplit("/", 1)[1]
        data = re.search(rf"\n\s*{short} =([^;]*);", dump("-p", "9", "-v", name))
        assert data is not None, name
        dumped = np.array([float(v) for v in data.group(1).replace("\n", " ").split(",")])
        np.testing.assert_allclose(dumped, values.ravel(), rtol=1e-6, err_msg=name)


def test_format_2_0_opens_into_the_same_datasets(wave_maps: Path) -> None:
    """results.h5 2.0 (booleans and the complex carrier value in h5py's types) opens with
    the variables and types of 2.1: booleans as booleans, ``carrier_value`` complex64."""
    assert results_version(V2_0_FILE) == "2.0"
    for group in ("maps", "trends", "peaks"):
        with open_results(V2_0_FILE, group) as old, open_results(wave_maps, group) as new:
            names = set(old.variables) - set(map_labels(old))
            assert names == set(new.variables) - set(map_labels(new)), group
            for name in names:
                assert old[name].dims == new[name].dims, (group, name)
                assert old[name].dtype.kind == new[name].dtype.kind, (group, name)
                assert old[name].attrs.get("units") == new[name].attrs.get("units"), name
                assert old[name].attrs.get("long_name") == new[name].attrs.get("long_name")
            assert old.attrs["interrupted"] is new.attrs["interrupted"] is False
    with (
        h5py.File(V2_0_FILE, "r") as raw,
        open_results(V2_0_FILE, "trends") as trends,
        open_results(V2_0_FILE, "peaks") as peaks,
        open_results(V2_0_FILE, "maps") as maps,
        open_results(wave_maps, "maps") as new_maps,
        open_results(wave_maps, "trends") as new_trends,
    ):
        assert trends.carrier_value.dtype == np.complex64 == new_trends.carrier_value.dtype
        np.testing.assert_array_equal(trends.carrier_value, raw["trends/carrier_value"][()])
        assert trends.ambiguity_flagged.dtype == peaks.used_in_fused.dtype == bool
        np.testing.assert_array_equal(peaks.used_in_fused, raw["peaks/used_in_fused"][()])
        for dataset in (maps, new_maps):
            assert all(
                type(dataset[label].attrs["displacement_measured"]) is bool
                for label in map_labels(dataset)
                if label != "fused"
            )
        assert maps.RB1.attrs["displacement_measured"] is bool(
            raw["maps/RB1"].attrs["displacement_measured"]
        )


WINDOW_VARIABLES = {"radius_cpp", "window_taper", "window_rule", "window_reason"}


def test_format_1_opens_into_the_same_datasets(evaporation: Simulated, tmp_path: Path) -> None:
    from holoview.cli import main

    out = tmp_path / "v2"
    argv = ["-q", "process", str(evaporation.path), "--out", str(out), "--maps", "--jobs", "1"]
    assert main([*argv, "--frames", "0:8", "--area", "0.01"]) == 0
    assert results_version(V1_FILE) == "1.0"
    with h5py.File(V1_FILE, "r") as raw:
        for group in ("maps", "trends", "peaks"):
            with open_results(V1_FILE, group) as old, open_results(out, group) as new:
                # each peak's window is written since issue 23 (2.0 readers ignore it)
                added = WINDOW_VARIABLES if group == "peaks" else set()
                assert set(old.variables) == set(new.variables) - added, group
                for name in old.variables:
                    assert old[name].dims == new[name].dims, (group, name)
                    assert old[name].attrs.get("units") == new[name].attrs.get("units"), name
        with open_results(V1_FILE, "maps") as maps:
            np.testing.assert_array_equal(maps.RB1.values, raw["maps/RB1"][:])
            np.testing.assert_array_equal(maps.time, raw["trends/time_s"][:])
            step, size = (
                raw["maps/RB1"].attrs["pixel_step_px"],
                raw["maps/RB1"].attrs["pixel_size_m"],
            )
            np.testing.assert_allclose(maps.x, np.arange(maps.sizes["x"]) * size[1])
            assert size[1] == pytest.approx(step[1] * raw.attrs["pixel_pitch_m"])
            assert maps.attrs["format_version"] == "1.0"
        with open_results(V1_FILE, "trends") as trends:
            np.testing.assert_array_equal(trends.mean_height_m, raw["trends/mean_height_m"][:])
            assert trends.fused_volume_m3.attrs["units"] == "m3"  # 1.0 wrote m^3


def test_maps_without_a_pixel_pitch_are_in_frame_pixels(
    evaporation: Simulated, tmp_path: Path
) -> None:
    """A .npy stack carries no pitch: y and x count frame pixels, units 1."""
    from holoview.acquire.recording_reader import RecordingReader
    from holoview.cli import main

    with RecordingReader(evaporation.path) as reader:
        frames = np.stack([reader.frame(i) for i in range(6)])
    np.save(tmp_path / "stack.npy", frames)
    out = tmp_path / "out"
    argv = ["-q", "process", str(tmp_path / "stack.npy"), "--out", str(out), "--maps"]
    argv += [*evaporation.label_args("RB1", "RF"), "--wavelength-nm", "532", "--fluid", "water"]
    assert main([*argv, "--fps", "20", "--jobs", "1"]) == 0
    with open_results(out, "maps") as maps:
        assert maps.y.attrs["units"] == "1" and "pixel" in maps.y.attrs["long_name"]
        step = 128 / maps.sizes["y"]
        np.testing.assert_allclose(maps.y, np.arange(maps.sizes["y"]) * step)
        np.testing.assert_allclose(maps.time, np.arange(6) / 20)
    export_results(out, "tiff", tmp_path / "stacks", maps=["RB1"])
    with tifffile.TiffFile(tmp_path / "stacks" / "RB1.tif") as tif:
        assert tif.imagej_metadata["unit"] == "pixel"


def test_results_errors_are_one_line(evaporation: Simulated, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a holoview results file"):
        open_results(evaporation.path)
    with pytest.raises(InputError, match="no such results file"):
        open_results(tmp_path / "missing")
    with pytest.raises(InputError, match="unknown results group 'truth'"):
        open_results(V1_FILE, "truth")
    newer = tmp_path / "newer.h5"
    with h5py.File(newer, "w") as f:
        f.attrs["format"] = "holoview-results"
        f.attrs["format_version"] = "3.0"
    with pytest.raises(InputError, match=r"version '3.0' is not read"):
        open_results(newer, "trends")


def test_a_label_named_like_a_dimension_is_refused(
    evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    fx, fy = evaporation.carriers["RB1"]
    argv = ["process", str(evaporation.path), "--out", str(tmp_path / "o")]
    status, _, err = run_cli([*argv, "--label", f"time={fx},{fy}"], capsys)
    assert status == 2
    assert "label 'time' is not usable" in err and len(err.strip().splitlines()) == 1
