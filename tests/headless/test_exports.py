"""``holoview export``: each format read back by its own ecosystem's reader.

NetCDF by the netCDF-C library (netCDF4) and xarray, Zarr by zarr, MAT v5 by
scipy.io.loadmat and v7.3 by h5py, TIFF stacks by tifffile; values compared with
``results.h5`` read by h5py. Streaming is checked on maps larger than the export's
chunk: the memory traced while exporting stays well below the maps' size.
"""

from __future__ import annotations

import os
import tracemalloc
from pathlib import Path

import h5py
import netCDF4
import numpy as np
import pytest
import scipy.io
import tifffile
import xarray as xr
import zarr
from headless_sim import Simulated, run_cli

from holoview.headless.results import cf, export_mat, exports
from holoview.headless.results.results_layout import RESULTS_VERSION, map_dimensions

V1_FILE = Path(__file__).parent / "data" / "results_v1.h5"
V2_0_FILE = Path(__file__).parent / "data" / "results_v2_0.h5"


@pytest.fixture(scope="module")
def run(evaporation: Simulated, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Evaporation processed with maps and a basin area, frames 0 to 29: results.h5."""
    from holoview.cli import main

    out = tmp_path_factory.mktemp("export") / "run"
    argv = ["-q", "process", str(evaporation.path), "--out", str(out), "--maps", "--jobs", "1"]
    assert main([*argv, "--frames", "0:30", "--area", "0.01"]) == 0
    return out / "results.h5"


def h5(run: Path, name: str) -> np.ndarray:
    with h5py.File(run, "r") as f:
        return f[name][()]


def carrier_value(run: Path) -> np.ndarray:
    """``/trends/carrier_value`` of results.h5: its two parts joined."""
    return h5(run, "trends/carrier_value_real") + 1j * h5(run, "trends/carrier_value_imag")


def labels_of(run: Path) -> list[str]:
    return [s.decode() for s in h5(run, "trends/label")]


def test_netcdf_read_back_by_netcdf_c_and_xarray(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.nc"
    done = exports.export_results(run, "netcdf", out)
    assert done.groups == ("maps", "trends", "peaks") and "fused" in done.maps
    with netCDF4.Dataset(out) as nc:
        assert nc.format_version == RESULTS_VERSION and nc.interrupted == 0
        fused = nc["maps"]["fused"]
        assert fused.dimensions == ("time", "y", "x") and fused.units == "m"
        np.testing.assert_array_equal(fused[:].filled(np.nan), h5(run, "maps/fused"))
        np.testing.assert_array_equal(nc["maps"]["x"][:], h5(run, "maps/x"))
        trends = nc["trends"]
        assert trends["mean_height_m"].dimensions == ("time", "label")
        assert list(trends["label"][:]) == labels_of(run)
        value = carrier_value(run)
        np.testing.assert_array_equal(trends["carrier_value_real"][:], value.real)
        np.testing.assert_array_equal(trends["carrier_value_imag"][:], value.imag)
        assert trends["carrier_value_imag"].units == "count"
        assert trends["fused_volume_m3"].units == "m3"
    with xr.open_dataset(out, group="peaks", engine="netcdf4") as peaks:
        np.testing.assert_array_equal(peaks.used_in_fused, h5(run, "peaks/used_in_fused") == 1)
        assert peaks.used_in_fused.dtype == bool


def test_zarr_read_back_by_zarr(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.zarr"
    exports.export_results(run, "zarr", out)
    root = zarr.open_group(out, mode="r")
    assert root.attrs["format"] == "holoview-results"
    fused = root["maps/fused"]
    assert fused.attrs["units"] == "m"
    assert fused.attrs["_ARRAY_DIMENSIONS"] == ["time", "y", "x"]
    assert fused.chunks[0] == 1
    np.testing.assert_array_equal(fused[:], h5(run, "maps/fused"))
    np.testing.assert_array_equal(root["trends/carrier_value"][:], carrier_value(run))
    with xr.open_zarr(out, group="trends") as trends:
        assert trends.mean_height_m.dims == ("time", "label")
        assert list(trends.label.values) == labels_of(run)


def test_mat_v5_read_back_by_scipy(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.mat"
    exports.export_results(run, "mat", out)
    mat = scipy.io.loadmat(out, simplify_cells=True)
    maps = mat["maps"]
    np.testing.assert_array_equal(maps["fused"], h5(run, "maps/fused"))  # (time, y, x)
    np.testing.assert_array_equal(maps["y"], h5(run, "maps/y"))
    assert maps["units"]["fused"] == "m" and maps["units"]["time"] == "s"
    assert [s.strip() for s in maps["labels"]] == [*sorted(labels_of(run)), "fused"]
    assert maps["attributes"]["RB1"]["alpha"] == pytest.approx(h5(run, "peaks/alpha")[0])
    trends = mat["trends"]
    np.testing.assert_array_equal(trends["mean_height_m"], h5(run, "trends/mean_height_m"))
    np.testing.assert_array_equal(trends["carrier_value"], carrier_value(run))
    assert [s.strip() for s in trends["label"]] == labels_of(run)
    assert trends["units"]["fused_volume_m3"] == "m3"
    assert mat["attributes"]["format_version"] == RESULTS_VERSION


def test_mat_v73_read_back_by_h5py(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "run.mat"
    exports.export_results(run, "mat", out, mat_version="7.3")
    assert out.read_bytes()[:19] == b"MATLAB 7.3 MAT-file"
    assert out.read_bytes()[124:128] == b"\x00\x02IM"
    with h5py.File(out, "r") as f:
        fused = f["maps/fused"]
        assert fused.attrs["MATLAB_class"] == b"single"
        np.testing.assert_array_equal(fused[()].transpose(2, 1, 0), h5(run, "maps/fused"))
        assert f["maps"].attrs["MATLAB_class"] == b"struct"
        label = f["trends/label"]
        assert label.attrs["MATLAB_class"] == b"char"
        rows = ["".join(map(chr, row)).strip() for row in label[()].T]
        assert rows == labels_of(run)
        value = f["trends/carrier_value"][()].T
        np.testing.assert_array_equal(value["real"] + 1j * value["imag"], carrier_value(run))
        np.testing.assert_array_equal(f["trends/time"][()], h5(run, "trends/time")[None, :])
        assert f["peaks/used_in_fused"].attrs["MATLAB_class"] == b"logical"


def test_tiff_stacks_read_back_by_tifffile_with_the_pixel_size(run: Path, tmp_path: Path) -> None:
    out = tmp_path / "stacks"
    done = exports.export_results(run, "tiff", out, maps=["fused", "RB1"])
    assert sorted(p.name for p in out.iterdir()) == ["RB1.tif", "fused.tif"]
    assert done.groups == ("maps",)
    with h5py.File(run, "r") as f:
        size_um = f["maps/fused"].attrs["pixel_size_m"] * 1e6
        times = f["maps/time"][()]
    with tifffile.TiffFile(out / "fused.tif") as tif:
        assert tif.is_imagej
        meta = tif.imagej_metadata
        assert meta["unit"] == "um"
        assert meta["finterval"] == pytest.approx(np.mean(np.diff(times)))
        assert meta["Labels"][3] == f"frame 3, t = {times[3]:.6f} s"
        assert meta["Properties"]["units"] == "m"
        numerator, denominator = tif.pages[0].tags["XResolution"].value
        assert denominator / numerator == pytest.approx(size_um[1], rel=1e-6)
        assert tif.series[0].axes == "TYX"
        np.testing.assert_array_equal(tif.asarray(), h5(run, "maps/fused"))


def test_format_1_exports_too(tmp_path: Path) -> None:
    exports.export_results(V1_FILE, "netcdf", tmp_path / "old.nc")
    with netCDF4.Dataset(tmp_path / "old.nc") as nc:
        assert nc["maps"]["RB1"].dimensions == ("time", "y", "x")
        assert nc["trends"]["fused_volume_m3"].units == "m3"
        np.testing.assert_array_equal(nc["maps"]["RB1"][:].filled(np.nan), h5(V1_FILE, "maps/RB1"))


def test_format_2_0_exports_as_2_1_does(run: Path, tmp_path: Path) -> None:
    """A 2.0 file's booleans and complex carrier value (h5py's HDF5 enum and compound
    types) export with the types a 2.1 file's export has."""
    exports.export_results(V2_0_FILE, "netcdf", tmp_path / "old.nc")
    exports.export_results(run, "netcdf", tmp_path / "new.nc")
    with netCDF4.Dataset(tmp_path / "old.nc") as old, netCDF4.Dataset(tmp_path / "new.nc") as new:
        for group in ("trends", "peaks"):
            for name, variable in new[group].variables.items():
                assert old[group][name].dtype == variable.dtype, (group, name)
        value = h5(V2_0_FILE, "trends/carrier_value")
        np.testing.assert_array_equal(old["trends"]["carrier_value_real"][:], value.real)
        np.testing.assert_array_equal(old["trends"]["carrier_value_imag"][:], value.imag)
        used = old["peaks"]["used_in_fused"]
        np.testing.assert_array_equal(used[:], h5(V2_0_FILE, "peaks/used_in_fused"))
        assert used.dtype == np.int8 and used.getncattr("dtype") == "bool"
        assert old.interrupted == 0


@pytest.fixture(scope="module")
def large_maps(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A format 2.0 file with one map of 100 frames of 256^2 (26 MB), written block by block."""
    path = tmp_path_factory.mktemp("large") / "results.h5"
    n, side = 100, 256
    with h5py.File(path, "w") as f:
        f.attrs.update({"format": "holoview-results", "format_version": "2.0"})
        group = f.create_group("maps")
        fused = group.create_dataset(
            "fused", shape=(n, side, side), dtype=np.float32, chunks=(1, side, side)
        )
        ramp = np.linspace(0, 1e-9, side, dtype=np.float32)
        for start in range(0, n, 10):
            fused[start : start + 10] = ramp[None, None, :] * np.arange(start, start + 10)[
                :, None, None
            ].astype(np.float32)
        scales = map_dimensions(
            group,
            frames=np.arange(n),
            times=np.arange(n) / 50.0,
            box_shape=(side, side),
            step_px=(4.0, 4.0),
            pixel_pitch_m=5e-6,
        )
        cf.attach(fused, scales)
        cf.describe(fused, units="m", long_name="height change", pixel_size_m=[2e-5, 2e-5])
    return path


@pytest.mark.slow
@pytest.mark.parametrize(
    "case",
    [
        ("netcdf", "o.nc", {}),
        ("zarr", "o.zarr", {}),
        ("mat", "o.mat", {"mat_version": "7.3"}),
        ("tiff", "o", {}),
    ],
    ids=["netcdf", "zarr", "mat73", "tiff"],
)
def test_maps_are_exported_chunk_by_chunk(
    large_maps: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    case: tuple[str, str, dict],
) -> None:
    """Memory traced while exporting 26 MB of maps in 2 MB chunks stays under half of it."""
    monkeypatch.setattr(exports, "CHUNK_BYTES", 2 * 2**20)
    total = 100 * 256 * 256 * 4
    to, name, options = case
    exports.export_results(V1_FILE, to, tmp_path / "small", **options)  # the imports done
    tracemalloc.start()
    try:
        exports.export_results(large_maps, to, tmp_path / name, **options)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < total / 2, f"{to}: {peak / 1e6:.1f} MB traced for {total / 1e6:.0f} MB of maps"
    assert (tmp_path / name).exists()


def test_mat_v5_over_two_gigabytes_is_refused_naming_v73(
    run: Path, tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The limit is MATLAB's (2 GB a variable); here lowered to the maps' size to reach it."""
    with h5py.File(run, "r") as f:
        maps_bytes = sum(f["maps"][n].nbytes for n in f["maps"] if f["maps"][n].ndim == 3)
    monkeypatch.setattr(export_mat, "MAT5_LIMIT_BYTES", maps_bytes)
    argv = ["export", str(run), "--to", "mat", "--out", str(tmp_path / "big.mat")]
    status, _, err = run_cli(argv, capsys)
    assert status == 2
    assert "holds per variable: give --mat-version 7.3" in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "big.mat").exists()
    assert run_cli([*argv, "--mat-version", "7.3"], capsys)[0] == 0


def test_cli_writes_one_line_and_refuses_mistakes_in_one_line(
    run: Path, evaporation: Simulated, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r.nc"
    status, stdout, _ = run_cli(
        ["export", str(run.parent), "--to", "netcdf", "--out", str(out)], capsys
    )
    assert status == 0 and stdout.strip().startswith(f"{out}: netcdf of maps, trends, peaks")
    cases = [
        (["--to", "netcdf", "--out", str(out)], "exists; give --overwrite"),
        (["--to", "tiff", "--out", str(tmp_path / "t"), "--map", "RB9"], "no map RB9"),
        (["--to", "zarr", "--out", str(out), "--overwrite"], "is a file; a zarr export is not"),
        (["--to", "mat", "--out", str(tmp_path / "no" / "r.mat")], "folder"),
    ]
    for args, message in cases:
        status, _, err = run_cli(["export", str(run), *args], capsys)
        assert status == 2, args
        assert message in err and len(err.strip().splitlines()) == 1, err
    status, _, err = run_cli(
        ["export", str(evaporation.path), "--to", "mat", "--out", str(tmp_path / "x.mat")], capsys
    )
    assert status == 2 and "not a holoview results file" in err


def test_overwrite_replaces_and_an_interrupted_export_leaves_nothing(
    run: Path, tmp_path: Path
) -> None:
    for to, name in (("netcdf", "r.nc"), ("zarr", "r.zarr"), ("tiff", "r"), ("mat", "r.mat")):
        target = tmp_path / name
        exports.export_results(run, to, target, maps=["RB1"])
        before = sorted(os.listdir(tmp_path))

        def stop(done: int, total: int) -> None:
            raise KeyboardInterrupt

        options = {"mat_version": "7.3"} if to == "mat" else {}
        with pytest.raises(KeyboardInterrupt):
            exports.export_results(run, to, target, overwrite=True, progress=stop, **options)
        assert sorted(os.listdir(tmp_path)) == before, to  # no temporary left, target kept
        exports.export_results(run, to, target, overwrite=True, maps=["fused"])
        assert sorted(os.listdir(tmp_path)) == before, to
    with tifffile.TiffFile(tmp_path / "r" / "fused.tif") as tif:
        assert tif.series[0].shape[0] == 30
    assert not (tmp_path / "r" / "RB1.tif").exists()


def test_tiff_of_results_without_maps_is_refused(evaporation: Simulated, tmp_path: Path) -> None:
    from holoview.cli import main
    from holoview.errors import InputError

    out = tmp_path / "plain"
    assert (
        main(["-q", "process", str(evaporation.path), "--out", str(out), "--frames", "0:10"]) == 0
    )
    with pytest.raises(
        InputError, match="holds no maps for TIFF: run holoview process with --maps"
    ):
        exports.export_results(out, "tiff", tmp_path / "t")
    done = exports.export_results(out, "netcdf", tmp_path / "t.nc")
    assert done.groups == ("trends", "peaks") and done.maps == ()
