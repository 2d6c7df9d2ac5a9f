"""holoview.api: recordings of every input kind as lazy frames, processing, errors, no Qt.

The frames the API gives are compared with the recording's own reader and with the
arrays the files were written from; the processed rate with the simulator's truth.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile
from headless_sim import Simulated

import holoview.api as hv
from holoview.acquire.recording_reader import RecordingReader
from holoview.errors import InputError


def first_frames(evaporation: Simulated, n: int = 6) -> np.ndarray:
    with RecordingReader(evaporation.path) as reader:
        return np.stack([reader.frame(i) for i in range(n)])


def test_a_holoview_recording_opens_with_frames_times_and_experiment(
    evaporation: Simulated,
) -> None:
    with hv.open_recording(evaporation.path) as rec:
        assert rec.kind == "hdf5"
        assert len(rec) == evaporation.frames
        assert rec.frames.chunks[0] == (1,) * evaporation.frames  # one frame per chunk
        np.testing.assert_array_equal(rec.frames[:6].compute(), first_frames(evaporation))
        assert rec.times is not None
        np.testing.assert_allclose(rec.times, evaporation.time_s - evaporation.time_s[0])
        assert rec.experiment is not None
        assert {p.label for p in rec.experiment.peaks} == {"RB1", "RF", "FB1"}
        assert rec.setup["wavelength_m"] == pytest.approx(evaporation.wavelength)
        frames = rec.to_xarray()
        assert frames.dims == ("time", "y", "x")
        assert frames.x.attrs["units"] == "m"
        assert float(frames.x[1]) == pytest.approx(rec.setup["pixel_pitch_m"])
        assert frames.time.attrs["units"] == "s"


def test_frames_survive_pickling_and_reopen_by_path(evaporation: Simulated) -> None:
    """What dask's process and distributed schedulers do with the frames."""
    with hv.open_recording(evaporation.path) as rec:
        copy = pickle.loads(pickle.dumps(rec.frames[2:5]))
    np.testing.assert_array_equal(copy.compute(), first_frames(evaporation)[2:5])


def write_video(path: Path, frames: np.ndarray) -> None:
    """Lossless 16-bit grey (FFV1), as OpenCV writes it headless."""
    params = [cv2.VIDEOWRITER_PROP_IS_COLOR, 0, cv2.VIDEOWRITER_PROP_DEPTH, cv2.CV_16U]
    fourcc = cv2.VideoWriter_fourcc(*"FFV1")
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, fourcc, 20.0, frames.shape[2:0:-1], params)
    assert writer.isOpened()
    for frame in frames:
        writer.write(frame)
    writer.release()


def test_every_input_kind_of_process_opens_lazily(evaporation: Simulated, tmp_path: Path) -> None:
    frames = first_frames(evaporation)
    tifffile.imwrite(tmp_path / "stack.tif", frames, photometric="minisblack")
    folder = tmp_path / "images"
    folder.mkdir()
    for i, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"img{i}.png"), frame)
    np.save(tmp_path / "stack.npy", frames)
    write_video(tmp_path / "movie.mkv", frames)
    for name, kind in (
        ("stack.tif", "tiff"),
        ("images", "folder"),
        ("stack.npy", "numpy"),
        ("movie.mkv", "video"),
    ):
        with hv.open_recording(tmp_path / name, fps=20) as rec:
            assert rec.kind == kind
            assert rec.frames.shape == frames.shape and rec.frames.dtype == frames.dtype
            np.testing.assert_array_equal(rec.frames.compute(), frames, err_msg=name)
            np.testing.assert_allclose(rec.times, np.arange(6) / 20)
            assert rec.experiment is None and rec.setup == {}
            assert rec.to_xarray().x.attrs["units"] == "1"
    with hv.open_recording(tmp_path / "stack.tif") as rec:
        assert rec.times is None  # a TIFF has no times, and no fps was given


def test_process_through_the_api_measures_the_true_rate(
    evaporation: Simulated, tmp_path: Path
) -> None:
    outcome = hv.process(
        evaporation.path,
        tmp_path / "out",
        labels={k: evaporation.carriers[k] for k in ("RB1", "FB1")},
        maps=True,
        frames=slice(0, 60),
        jobs=1,
        report=False,
    )
    assert outcome.analysis.fit is not None
    truth = np.polyfit(evaporation.time_s[:60], evaporation.mean_height_m[:60], 1)[0]
    assert outcome.analysis.fit.rate == pytest.approx(truth, rel=0.01)
    with hv.open_results(tmp_path / "out", "maps") as maps:
        assert maps.sizes["time"] == 60


def test_mistakes_are_input_errors(evaporation: Simulated, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="--size must be from 8"):
        hv.simulate(tmp_path / "tiny.h5", "waves", size=4)
    with pytest.raises(InputError, match="argument --scenario: invalid choice"):
        hv.simulate(tmp_path / "x.h5", "tides")
    with pytest.raises(InputError, match="exists; holoview does not overwrite"):
        hv.simulate(evaporation.path, "evaporation")
    with pytest.raises(InputError, match="no such file"):
        hv.open_recording(tmp_path / "missing.h5")
    with pytest.raises(InputError, match="frames takes"):
        hv.process(evaporation.path, tmp_path / "o", frames=slice(0, 10, 2))


def test_the_api_loads_no_qt(tmp_path: Path) -> None:
    code = (
        "import sys\n"
        "import holoview.api as hv\n"
        f"hv.simulate({str(tmp_path / 'r.h5')!r}, 'evaporation', size=32, frames=2)\n"
        "with hv.open_recording("
        f"{str(tmp_path / 'r.h5')!r}) as rec: rec.frames.sum().compute()\n"
        "qt = ('PyQt6', 'PyQt5', 'PySide6', 'PySide2', 'pyqtgraph')\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in qt or "
        "m.startswith('holoview.ui')))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"
