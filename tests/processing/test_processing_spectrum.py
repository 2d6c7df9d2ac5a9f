"""The planned real FFT, its wisdom cache, and the display spectrum."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from holoview.errors import InputError
from holoview.processing.fourier import fastmath, fftplans
from holoview.processing.fourier.fastmath import MAX_ERROR, angle
from holoview.processing.fourier.spectrum import display_spectrum, frequencies, log_magnitude, rfft2


@pytest.mark.parametrize("shape", [(64, 64), (48, 80), (81, 63)])
def test_rfft2_matches_numpy(shape: tuple[int, int]) -> None:
    frame = np.random.default_rng(1).integers(0, 4096, shape, dtype=np.uint16)
    kept = frame.copy()
    ours = rfft2(frame)
    np.testing.assert_allclose(ours, np.fft.rfft2(frame.astype(np.float64)), rtol=1e-5, atol=0.5)
    np.testing.assert_array_equal(frame, kept)


@pytest.mark.parametrize("shape", [(64, 64), (48, 80), (81, 63), (50, 33)])
def test_display_spectrum_is_the_centred_log_magnitude(shape: tuple[int, int]) -> None:
    frame = np.random.default_rng(2).random(shape).astype(np.float32) * 100
    expected = np.fft.fftshift(np.log1p(np.abs(np.fft.fft2(frame.astype(np.float64)))))
    shown = display_spectrum(frame)
    assert shown.dtype == np.float32 and shown.shape == shape
    np.testing.assert_allclose(shown, expected, rtol=1e-4, atol=1e-4)


def test_frequency_axes_locate_a_carrier() -> None:
    rows, cols = 60, 90
    y, x = np.mgrid[:rows, :cols]
    frame = 100 + 50 * np.cos(2 * np.pi * (10 / cols * x + 6 / rows * y))
    shown = display_spectrum(frame)
    fy, fx = frequencies((rows, cols))
    shown[rows // 2, cols // 2] = 0  # zero frequency
    iy, ix = np.unravel_index(np.argmax(shown), shown.shape)
    assert {(round(fx[ix] * cols), round(fy[iy] * rows))} <= {(10, 6), (-10, -6)}


def test_log_magnitude_rejects_a_mismatched_half_spectrum() -> None:
    with pytest.raises(ValueError, match="does not match"):
        log_magnitude(np.zeros((8, 8), np.complex64), (8, 8))


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (np.zeros((0, 5)), "empty"),
        (np.zeros(64), "2-D"),
        (np.zeros((32, 32, 3)), "colour"),
        (np.zeros((4, 64)), "too small"),
        (np.zeros((32, 32), complex), "dtype"),
    ],
)
def test_bad_frames_give_one_line_errors(frame: np.ndarray, message: str) -> None:
    with pytest.raises(InputError, match=message):
        display_spectrum(frame)


def test_wisdom_is_saved_and_reused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import pyfftw

    monkeypatch.setenv("HOLOVIEW_CACHE_DIR", str(tmp_path))
    # the process's wisdom starts empty: what an earlier test on the same worker planned
    # or loaded stays in FFTW's wisdom, and with this shape in it nothing was planned or
    # saved (CI, once in many runs)
    pyfftw.forget_wisdom()
    fftplans.forget_loaded_wisdom()
    fftplans.clear_plans()
    shape = (96, 120)
    fftplans.rfft2_plan(shape, threads=1, effort="FFTW_MEASURE")
    wisdom = tmp_path / "wisdom.bin"
    assert wisdom.is_file() and wisdom.stat().st_size > 0
    # a fresh process would import the file; forget_wisdom stands in for the restart
    pyfftw.forget_wisdom()
    fftplans.forget_loaded_wisdom()
    fftplans.clear_plans()
    assert fftplans.load_wisdom()
    plan, planned = fftplans._build("rfft2", shape, 1, "FFTW_MEASURE")
    assert not planned, "the saved wisdom should cover the shape (FFTW_WISDOM_ONLY)"
    assert plan.input_array.shape == shape


def test_unwritable_cache_only_warns(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("a file where the cache directory should be")
    monkeypatch.setenv("HOLOVIEW_CACHE_DIR", str(blocker / "cache"))
    fftplans.forget_loaded_wisdom()
    with caplog.at_level(logging.WARNING, logger="holoview.processing.fourier.fftplans"):
        assert not fftplans.save_wisdom()
    assert "cannot write FFT wisdom" in caplog.text


def test_corrupt_wisdom_is_ignored_with_a_warning(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setenv("HOLOVIEW_CACHE_DIR", str(tmp_path))
    (tmp_path / "wisdom.bin").write_bytes(b"\x05\x00\x00\x00garbage")
    fftplans.forget_loaded_wisdom()
    with caplog.at_level(logging.WARNING, logger="holoview.processing.fourier.fftplans"):
        assert not fftplans.load_wisdom()
    assert "unusable FFT wisdom" in caplog.text


def test_cache_dir_follows_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("HOLOVIEW_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", "/somewhere")
    assert fftplans.cache_dir() == Path("/somewhere/holoview")
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert fftplans.cache_dir() == Path.home() / ".cache" / "holoview"


def test_fft_friendly_sizes() -> None:
    assert [fftplans.fft_friendly(n) for n in (1, 7, 142, 251, 256)] == [2, 8, 144, 256, 256]


@pytest.mark.parametrize("numpy_arctan2", [False, True])
def test_fast_angle_matches_numpy(numpy_arctan2: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    # both paths run on any CPU: numpy's arctan2 is only slower where it is not vectorised
    monkeypatch.setattr(fastmath, "NUMPY_ARCTAN2", numpy_arctan2)
    rng = np.random.default_rng(3)
    z = (rng.standard_normal((50, 70)) + 1j * rng.standard_normal((50, 70))).astype(np.complex64)
    z[0, :6] = [1, -1, 1j, -1j, complex(-1, 0.0), complex(-1, -0.0)]
    z[1, :3] = [1e-20 + 1e-25j, -3e30 + 1j, 2e-30j]
    z[2, :4] = [complex(-0.0, 1), complex(-0.0, -1), complex(0.0, -1), complex(1, -0.0)]
    kept = z.copy()
    ours = angle(z)
    assert ours.dtype == np.float32
    np.testing.assert_allclose(
        ours, np.angle(z.astype(np.complex128)), rtol=0, atol=MAX_ERROR + 1e-6
    )
    np.testing.assert_array_equal(z, kept)
