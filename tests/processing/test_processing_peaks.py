"""Finding carriers: significance, twins, sub-bin estimates, harmonics, sums, real holograms."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tifffile
from processing_synth import frame

from holoview.errors import InputError
from holoview.processing.peaks.detection import Peak, find_peaks, flag_relations


def _canonical(carrier: tuple[float, float]) -> tuple[float, float]:
    fx, fy = carrier
    return (fx, fy) if fx > 0 or (fx == 0 and fy > 0) else (-fx, -fy)


def _match(peaks: list[Peak], carrier: tuple[float, float], shape: tuple[int, int]) -> Peak:
    fx, fy = _canonical(carrier)
    best = min(
        peaks,
        key=lambda p: np.hypot((p.carrier[0] - fx) * shape[1], (p.carrier[1] - fy) * shape[0]),
    )
    assert np.hypot((best.carrier[0] - fx) * shape[1], (best.carrier[1] - fy) * shape[0]) < 0.2, (
        best
    )
    return best


@pytest.mark.parametrize("shape", [(256, 256), (200, 320), (243, 250)])
def test_carriers_found_once_with_sub_bin_accuracy(shape: tuple[int, int]) -> None:
    carriers = [(0.1234, 0.0711), (-0.2107, 0.1803), (0.0502, -0.3109)]
    amplitudes = [0.12, 0.02, 0.015]
    f = frame(shape, carriers, amplitudes, [0.3, 1.0, 2.0], rng=np.random.default_rng(4))
    kept = f.copy()
    peaks = find_peaks(f)
    np.testing.assert_array_equal(f, kept)
    assert len(peaks) == 3, peaks
    assert [p.amplitude for p in peaks] == sorted((p.amplitude for p in peaks), reverse=True)
    for carrier, amplitude in zip(carriers, amplitudes, strict=True):
        p = _match(peaks, carrier, shape)
        assert p.carrier[0] > 0 or (p.carrier[0] == 0 and p.carrier[1] > 0), "canonical twin kept"
        assert p.amplitude == pytest.approx(amplitude, rel=0.08)
        assert p.snr > 8 and not p.flags & {"harmonic", "sum", "overlap"}


def test_twin_is_recognised_not_listed() -> None:
    shape = (128, 128)
    f = frame(shape, [(-0.2, -0.15)], [0.1], [0.0], rng=np.random.default_rng(5))
    peaks = find_peaks(f)
    assert len(peaks) == 1
    assert peaks[0].carrier == pytest.approx((0.2, 0.15), abs=0.2 / 128)
    flipped = peaks[0].flipped()
    assert flipped.carrier == pytest.approx((-0.2, -0.15), abs=0.2 / 128)
    assert flipped.flipped() == peaks[0]


@pytest.mark.parametrize("bits", [8, 10, 12, 16])
def test_bit_depths(bits: int) -> None:
    shape = (128, 160)
    full = 2**bits - 1
    carriers, amplitudes = [(0.2, 0.1), (0.05, 0.3)], [0.15, 0.05]
    f = frame(
        shape, carriers, amplitudes, [0.0, 1.0], photons=0.4 * full, rng=np.random.default_rng(bits)
    )
    f = np.clip(f, 0, full).astype(np.uint8 if bits == 8 else np.uint16)
    peaks = find_peaks(f)
    assert len(peaks) == 2
    for c, a in zip(carriers, amplitudes, strict=True):
        assert _match(peaks, c, shape).amplitude == pytest.approx(a, rel=0.1)


def test_harmonic_and_sum_are_flagged() -> None:
    shape = (256, 256)
    f1, f2 = (0.11, 0.05), (0.02, 0.17)
    harmonic = (0.22, 0.10)
    total = (0.13, 0.22)
    f = frame(
        shape,
        [f1, f2, harmonic, total],
        [0.12, 0.06, 0.01, 0.008],
        [0, 1, 2, 3],
        rng=np.random.default_rng(6),
    )
    peaks = find_peaks(f)
    assert len(peaks) == 4
    assert "harmonic" in _match(peaks, harmonic, shape).flags
    assert "sum" in _match(peaks, total, shape).flags
    assert not _match(peaks, f1, shape).flags & {"harmonic", "sum"}
    assert not _match(peaks, f2, shape).flags & {"harmonic", "sum"}


def test_aliased_harmonic_is_flagged() -> None:
    # 2 x 0.3 = 0.6 aliases to -0.4: the second order of a carrier near Nyquist
    shape = (200, 200)
    f = frame(shape, [(0.3, 0.1), (-0.4, 0.2)], [0.1, 0.01], [0, 0], rng=np.random.default_rng(7))
    peaks = find_peaks(f)
    assert "harmonic" in _match(peaks, (-0.4, 0.2), shape).flags


def test_near_nyquist_carrier_found_and_flagged() -> None:
    shape = (180, 240)
    carrier = (0.48, -0.46)
    f = frame(shape, [carrier], [0.1], [0.0], rng=np.random.default_rng(8))
    peaks = find_peaks(f)
    assert len(peaks) == 1
    assert "near_nyquist" in _match(peaks, carrier, shape).flags


def test_close_peaks_flagged_as_overlapping() -> None:
    shape = (256, 256)
    carriers = [(0.2, 0.1), (0.2 + 5 / 256, 0.1)]
    f = frame(shape, carriers, [0.1, 0.08], [0, 0], rng=np.random.default_rng(9))
    peaks = find_peaks(f)
    assert len(peaks) == 2 and all("overlap" in p.flags for p in peaks)
    # with an explicit small radius they no longer overlap
    assert not any("overlap" in p.flags for p in flag_relations(peaks, shape, radius=2 / 256))


def test_threshold_is_relative_to_the_local_background() -> None:
    shape = (256, 256)
    rng = np.random.default_rng(10)
    # a weak carrier in a quiet spectrum is found; nothing is found in pure noise
    f = frame(shape, [(0.2, 0.2)], [0.004], [0.0], photons=2000, rng=rng)
    assert len(find_peaks(f)) == 1
    noise = rng.poisson(2000, shape).astype(np.uint16)
    assert find_peaks(noise) == []
    # a stricter threshold drops it
    assert find_peaks(f, threshold=1e4) == []


def test_dc_region_and_max_peaks() -> None:
    shape = (128, 128)
    carriers = [(0.02, 0.01), (0.3, 0.1), (0.1, 0.35)]
    f = frame(shape, carriers, [0.1, 0.05, 0.04], [0, 0, 0], rng=np.random.default_rng(11))
    found = find_peaks(f, dc_radius=0.05)
    assert len(found) == 2
    assert len(find_peaks(f, dc_radius=0.05, max_peaks=1)) == 1
    assert len(find_peaks(f, dc_radius=0.0)) == 3


def test_peak_helpers() -> None:
    p = Peak((0.1, 0.2), 0.05, 30.0)
    q = p.relabelled("RB1", alpha=0.333)
    assert (q.label, q.alpha, q.carrier) == ("RB1", 0.333, p.carrier)
    assert p.with_flags({"weak"}).flags == frozenset({"weak"})
    with pytest.raises(AttributeError):
        p.label = "x"  # type: ignore[misc]


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (np.zeros((0, 0)), "empty"),
        (np.arange(100.0), "2-D"),
        (np.zeros((64, 64, 3), np.uint8), "colour"),
        (np.full((64, 64), np.nan), "NaN"),
        (np.full((64, 64), 700, np.uint16), "constant"),
        (np.full((64, 64), 4095, np.uint16), "saturated"),
    ],
)
def test_bad_frames(bad: np.ndarray, message: str) -> None:
    with pytest.raises(InputError, match=message):
        find_peaks(bad)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"threshold": 0.5}, "threshold"),
        ({"dc_radius": 0.7}, "dc_radius"),
        ({"max_peaks": 0}, "max_peaks"),
    ],
)
def test_bad_parameters(kwargs: dict, message: str) -> None:
    f = frame((64, 64), [(0.2, 0.1)], [0.1], [0.0], rng=np.random.default_rng(12))
    with pytest.raises(InputError, match=message):
        find_peaks(f, **kwargs)


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("paramecium_oa_oof.tif", (-0.3328, 0.2559)),
        ("paramecium_oa_oof_background.tif", (-0.3328, 0.2559)),
        ("usaf_oa.tif", (-0.3506, 0.3584)),
    ],
)
def test_real_holograms_carrier_found_twin_rejected(
    real_data: Path, name: str, expected: tuple[float, float]
) -> None:
    image = tifffile.imread(real_data / name)
    kept = image.copy()
    peaks = find_peaks(image)
    np.testing.assert_array_equal(image, kept)
    main = peaks[0]
    fx, fy = _canonical(expected)
    # the README's figures are integer bins of a Hann-windowed FFT: within 3 bins
    assert abs(main.carrier[0] - fx) * image.shape[1] < 3
    assert abs(main.carrier[1] - fy) * image.shape[0] < 3
    assert main.amplitude > 2 * peaks[1].amplitude
    twin = np.array([-fx, -fy])
    for p in peaks:
        assert np.hypot(*(np.array(p.carrier) - twin)) > 0.01, "the twin must not be listed"


def test_real_hologram_twin_demodulates_to_the_conjugate(real_data: Path) -> None:
    # a real frame's spectrum is Hermitian: the twin's field is the conjugate field
    from holoview.processing.maps.demodulate import Demodulator

    image = tifffile.imread(real_data / "paramecium_oa_oof.tif")
    main = find_peaks(image)[0]
    results = [
        Demodulator(image.shape, [peak], radius=0.08, reference="synthetic").process(image)
        for peak in (main, main.flipped())
    ]
    field, twin = results[0].peaks[0].field, results[1].peaks[0].field
    scale = np.abs(field).max()
    np.testing.assert_allclose(twin, np.conj(field), atol=1e-4 * scale, rtol=0)
    assert results[0].peaks[0].mask.mean() > 0.9 and np.isfinite(results[0].peaks[0].noise)
