"""The Demodulator: reference modes, box demodulation against the naive way, flags, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from processing_synth import BENCH, WAVELENGTH, bench_frame, bump, frame, intensity

from holoview.errors import InputError
from holoview.processing.fourier.boxes import UNTRUSTED_BORDER, box_shape_for
from holoview.processing.fourier.resample import box_positions
from holoview.processing.fourier.windows import auto_radii, radial_window
from holoview.processing.maps.demod_results import FRAME_FLAGS, PEAK_RESULT_FLAGS
from holoview.processing.maps.demodulate import Demodulator
from holoview.processing.maps.heights import height_to_phase
from holoview.processing.peaks.detection import Peak, find_peaks, refine_carriers

SHAPE = (256, 256)
PHOTONS = 800.0


def bench_peaks() -> list[Peak]:
    return [Peak(c, a, 100.0, label=n, alpha=al) for n, c, a, al in BENCH]


def truth_on_box(demod: Demodulator, height: float, sigma: float) -> np.ndarray:
    rows, cols = demod.shape
    y, x = np.meshgrid(*box_positions(demod.box_shape, demod.shape), indexing="ij")
    return height * np.exp(-((y - rows / 2) ** 2 + (x - cols / 2) ** 2) / (2 * sigma**2))


def shot_noise_bound(demod: Demodulator, i: int, frames: int) -> float:
    """Height noise (m) of peak i: sqrt(frames) x sqrt(eta / (2 N)) / A, in metres."""
    peak = demod.peaks[i]
    phase = np.sqrt(frames) * np.sqrt(demod.area_fraction(i) / (2 * PHOTONS)) / peak.amplitude
    return phase * WAVELENGTH / (4 * np.pi * peak.alpha)


@pytest.mark.parametrize("reference", ["relative", "absolute"])
def test_referenced_modes_reach_the_shot_noise_bound(reference: str) -> None:
    rng = np.random.default_rng(20)
    demod = Demodulator(SHAPE, bench_peaks(), reference=reference, wavelength=WAVELENGTH)
    first = demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    assert "reference" in first.flags and all(not r.phase.any() for r in first.peaks)
    truth = truth_on_box(demod, 5e-9, 30)
    errors: dict[int, list[float]] = {i: [] for i in range(4)}
    for _ in range(4):
        result = demod.process(bench_frame(SHAPE, bump(SHAPE, 5e-9, 30), rng=rng))
        for i, r in enumerate(result.peaks):
            # the frame is not periodic: leave out the box's edge, where the field dips
            errors[i].append(float(np.mean((r.delta_h - truth)[2:-2, 2:-2] ** 2)))
        if reference == "relative":
            demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    for i in range(4):
        rms = np.sqrt(np.mean(errors[i]))
        assert rms < 1.2 * shot_noise_bound(demod, i, 2), demod.peaks[i].label
    # and the per-frame noise estimate is close to what the errors show
    rb1 = result.peaks[0]
    assert rb1.noise_height == pytest.approx(np.sqrt(np.mean(errors[0])), rel=0.25)


def test_synthetic_mode_recovers_the_full_phase() -> None:
    rng = np.random.default_rng(21)
    demod = Demodulator(SHAPE, bench_peaks(), reference="synthetic", wavelength=WAVELENGTH)
    truth = truth_on_box(demod, 60e-9, 30)
    result = demod.process(bench_frame(SHAPE, bump(SHAPE, 60e-9, 30), rng=rng))
    assert "reference" not in result.flags
    for i, r in enumerate(result.peaks):
        expected = height_to_phase(truth, r.peak.alpha, WAVELENGTH) + 0.7 * i
        error = np.angle(np.exp(1j * (r.phase - expected)))[3:-3, 3:-3]  # edges: non-periodic frame
        assert (
            np.sqrt(np.mean(error**2))
            < 4 * np.sqrt(demod.area_fraction(i) / (2 * PHOTONS)) / r.peak.amplitude
        )


def naive_field(f: np.ndarray, peak: Peak, kind: str, radius: float) -> np.ndarray:
    fy = np.fft.fftfreq(f.shape[0])[:, None]
    fx = np.fft.fftfreq(f.shape[1])[None, :]
    dfx = (fx - peak.carrier[0] + 0.5) % 1 - 0.5
    dfy = (fy - peak.carrier[1] + 0.5) % 1 - 0.5
    w = radial_window(kind, np.hypot(dfx, dfy), radius)
    return np.fft.ifft2(np.fft.fft2(f.astype(np.float64)) * w)


@pytest.mark.parametrize(
    ("shape", "carrier"),
    [
        ((256, 256), (0.21, 0.13)),  # positive half
        ((192, 256), (-0.17, 0.31)),  # conjugate half, non-square
        ((256, 256), (0.015, 0.3)),  # box straddles fx = 0
        ((192, 256), (0.46, -0.44)),  # box wraps past Nyquist
    ],
)
@pytest.mark.parametrize("kind", ["raised-cosine", "top-hat", "tukey"])
def test_box_demodulation_equals_the_naive_full_size_way(
    shape: tuple[int, int], carrier: tuple[float, float], kind: str
) -> None:
    rng = np.random.default_rng(22)
    f = frame(shape, [carrier, (0.1, -0.2)], [0.1, 0.05], [rng.random(shape) * 2, 0.0], rng=rng)
    peak = Peak(carrier, 0.1, 50.0)
    radius = 0.04
    demod = Demodulator(shape, [peak], window=kind, radius=radius, reference="synthetic")
    result = demod.process(f)
    field = demod.upsample(result.peaks[0].field)
    rows, cols = shape
    y, x = np.mgrid[:rows, :cols]
    k0y, k0x = round(carrier[1] * rows), round(carrier[0] * cols)
    ours = field * np.exp(2j * np.pi * (k0x * x / cols + k0y * y / rows))
    naive = naive_field(f, peak, kind, radius)
    scale = np.abs(naive).max()
    np.testing.assert_allclose(ours, naive, atol=2e-4 * scale, rtol=0)


def test_field_amplitude_is_in_counts_and_the_mean_phase_follows_a_piston() -> None:
    rng = np.random.default_rng(23)
    # carriers on FFT bins: the frame is periodic, so no edge effect lowers the mean field
    peaks = [Peak((-38 / 256, 44 / 256), 0.1225, 100.0), Peak((51 / 256, 13 / 256), 0.0177, 50.0)]
    carriers = [p.carrier for p in peaks]
    amplitudes = [p.amplitude for p in peaks]
    for reference in ("synthetic", "absolute", "relative"):
        demod = Demodulator(SHAPE, peaks, reference=reference)
        total = 0.0
        phases = [0.4, -0.9]
        demod.process(frame(SHAPE, carriers, amplitudes, phases, rng=rng))
        for step in (0.5, 0.7, -0.3, 0.6, 0.6, 0.6):
            total += step
            result = demod.process(
                frame(SHAPE, carriers, amplitudes, [p + total for p in phases], rng=rng)
            )
        rb1 = result.peaks[0]
        assert abs(rb1.carrier_value) == pytest.approx(PHOTONS * rb1.peak.amplitude, rel=0.02)
        expected = {"relative": 0.6, "absolute": total, "synthetic": 0.4 + total}[reference]
        assert rb1.mean_phase == pytest.approx(np.angle(np.exp(1j * expected)), abs=0.01)
        # in time the mean phase is unwrapped past pi
        unwrapped = {"relative": total, "absolute": total, "synthetic": 0.4 + total}[reference]
        assert rb1.mean_phase_unwrapped == pytest.approx(unwrapped, abs=0.02)
        assert float(np.median(rb1.phase)) == pytest.approx(
            unwrapped if reference != "relative" else 0.6, abs=0.02
        )


def test_a_big_step_is_flagged() -> None:
    rng = np.random.default_rng(24)
    peak = bench_peaks()[0]
    demod = Demodulator(SHAPE, [peak])
    demod.process(frame(SHAPE, [peak.carrier], [peak.amplitude], [0.0], rng=rng))
    small = demod.process(frame(SHAPE, [peak.carrier], [peak.amplitude], [1.0], rng=rng))
    big = demod.process(frame(SHAPE, [peak.carrier], [peak.amplitude], [1.0 + 2.8], rng=rng))
    assert "phase_step" not in small.peaks[0].flags
    assert "phase_step" in big.peaks[0].flags


def test_reset_reference_starts_over() -> None:
    rng = np.random.default_rng(25)
    demod = Demodulator(SHAPE, bench_peaks(), reference="absolute")
    demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    assert demod.process(bench_frame(SHAPE, 0.0, rng=rng)).index == 1
    demod.reset_reference()
    again = demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    assert again.index == 0 and "reference" in again.flags


@pytest.mark.parametrize("reference", ["relative", "absolute", "synthetic"])
def test_break_sequence_pairs_no_frames_across_a_jump(reference: str) -> None:
    """A replay's jump: relative maps start over, an absolute reference stays, no step flagged."""
    rng = np.random.default_rng(26)
    peak = bench_peaks()[0]

    def piston(phase: float) -> np.ndarray:
        return frame(SHAPE, [peak.carrier], [peak.amplitude], [phase], rng=rng)

    demod = Demodulator(SHAPE, [peak], reference=reference)
    demod.process(piston(0.0))
    demod.process(piston(0.5))
    demod.break_sequence()
    jumped = demod.process(piston(0.5 + 2.8)).peaks[0]  # a step the demodulator would flag
    after = demod.process(piston(0.5 + 2.8 + 0.4)).peaks[0]
    assert "phase_step" not in jumped.flags
    wrapped = float(np.angle(np.exp(1j * 3.3)))
    if reference == "relative":
        assert "reference" in jumped.flags and not jumped.phase.any()
        assert after.mean_phase == pytest.approx(0.4, abs=0.02)
    elif reference == "absolute":
        assert "reference" not in jumped.flags  # still against the first frame
        assert jumped.mean_phase == pytest.approx(wrapped, abs=0.02)
        assert jumped.mean_phase_unwrapped == pytest.approx(wrapped, abs=0.02)
        assert after.mean_phase_unwrapped == pytest.approx(wrapped + 0.4, abs=0.02)
    else:
        assert jumped.mean_phase_unwrapped == pytest.approx(jumped.mean_phase, abs=1e-6)
        assert after.mean_phase_unwrapped - jumped.mean_phase_unwrapped == pytest.approx(
            0.4, abs=0.02
        )


@pytest.mark.parametrize("reference", ["relative", "absolute", "synthetic"])
@pytest.mark.parametrize("with_alpha", [True, False])
def test_auto_unwrapping_only_when_wrapped(reference: str, with_alpha: bool) -> None:
    rng = np.random.default_rng(26)
    peaks = bench_peaks()
    if not with_alpha:
        peaks = [p.relabelled(p.label, None) for p in peaks]
    demod = Demodulator(SHAPE, peaks, reference=reference, radius=0.06, unwrap="auto")
    height = 300e-9  # RB1: 2.4 rad, RB2: 11.8 rad at the top of the bump
    demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    calm = demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    if reference != "synthetic":  # a synthetic map can wrap at the frame's edges
        assert not any(r.unwrapped for r in calm.peaks)
    wavy = demod.process(bench_frame(SHAPE, bump(SHAPE, height, 40), rng=rng))
    truth = truth_on_box(demod, height, 40)
    for i, r in enumerate(wavy.peaks):
        alpha = BENCH[i][3]
        expected = height_to_phase(truth, alpha, WAVELENGTH)
        error = r.phase - expected
        if reference == "synthetic":
            error = error - np.median(error)
        error = error[4:-4, 4:-4]
        if expected.max() > 1.2 * np.pi:
            assert r.unwrapped, BENCH[i][0]
        assert np.abs(error).max() < 1.0, BENCH[i][0]
        assert np.sqrt(np.mean(error**2)) < 0.3, BENCH[i][0]


def test_never_unwrap_leaves_wraps() -> None:
    rng = np.random.default_rng(27)
    demod = Demodulator(SHAPE, bench_peaks(), unwrap="never", radius=0.06)
    demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    result = demod.process(bench_frame(SHAPE, bump(SHAPE, 300e-9, 40), rng=rng))
    rb2 = result.peaks[3]
    assert not rb2.unwrapped and np.abs(rb2.phase).max() <= np.pi + 1e-3


def test_non_square_frames_and_aperture() -> None:
    shape = (192, 256)
    rng = np.random.default_rng(28)
    peaks = bench_peaks()
    rows, cols = shape
    y, x = np.ogrid[:rows, :cols]
    aperture = (y - rows / 2) ** 2 + (x - cols / 2) ** 2 < 70**2
    demod = Demodulator(shape, peaks, aperture=aperture, wavelength=WAVELENGTH)
    demod.process(bench_frame(shape, 0.0, rng=rng))
    result = demod.process(bench_frame(shape, bump(shape, 3e-9, 30), rng=rng))
    assert result.frame_shape == shape and result.box_shape == box_shape_for(shape, demod.radius)
    for r in result.peaks:
        assert r.field.shape == r.phase.shape == r.mask.shape == result.box_shape
        assert r.mask.mean() < 0.6  # the disc covers about 31 % of the frame
    assert result.by_label("FB1").peak.label == "FB1"
    narrower = demod.with_peaks(peaks[:2], radius=0.04)
    assert narrower.aperture is not None and narrower.box_shape != demod.box_shape
    r = narrower.process(bench_frame(shape, 0.0, rng=rng)).peaks[0]
    assert r.mask.mean() < 0.6
    with pytest.raises(KeyError):
        result.by_label("nope")


def test_dark_pixels_are_masked() -> None:
    rng = np.random.default_rng(29)
    peak = bench_peaks()[0]
    cols = SHAPE[1]
    x = np.arange(cols)[None, :]
    modulation = np.where(x < cols // 2, 1.0, 0.02)  # right half: fringes nearly gone
    mean = PHOTONS * (
        1 + modulation * (intensity(SHAPE, [peak.carrier], [peak.amplitude], [0.0]) - 1)
    )
    demod = Demodulator(SHAPE, [peak], reference="synthetic")
    r = demod.process(rng.poisson(mean).astype(np.uint16)).peaks[0]
    by, bx = np.meshgrid(*box_positions(demod.box_shape, SHAPE), indexing="ij")
    # the frame's border is untrusted whatever the amplitude (peak_windows.border_mask)
    border = UNTRUSTED_BORDER / r.radius
    inside = (np.minimum(by, SHAPE[0] - by) > border) & (np.minimum(bx, cols - bx) > border)
    assert not r.mask[~inside].any()
    assert r.mask[inside & (bx < cols / 2 - 20)].mean() > 0.95
    assert r.mask[bx > cols / 2 + 20].mean() < 0.05
    assert "low_amplitude" not in r.flags


def test_flagged_frames_keep_the_stream_going() -> None:
    rng = np.random.default_rng(30)
    demod = Demodulator(SHAPE, bench_peaks(), reference="absolute", saturation=4095)
    demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    bad = bench_frame(SHAPE, 0.0, rng=rng).astype(np.float32)
    bad[10, 10] = np.nan
    kept = bad.copy()
    nan_result = demod.process(bad)
    np.testing.assert_array_equal(bad, kept)
    assert nan_result.flags == {"nonfinite"} and nan_result.peaks == ()
    assert nan_result.flags <= set(FRAME_FLAGS)
    constant = demod.process(np.full(SHAPE, 4095, np.uint16))
    assert {"no_signal", "saturated"} <= constant.flags <= set(FRAME_FLAGS)
    assert all(r.flags <= set(PEAK_RESULT_FLAGS) for r in constant.peaks)
    assert all("low_amplitude" in r.flags and not r.mask.any() for r in constant.peaks)
    # the reference survived: a good frame still compares with the first one
    good = demod.process(bench_frame(SHAPE, 0.0, rng=rng))
    assert not good.flags and all(abs(r.mean_phase) < 0.05 for r in good.peaks)


def test_inputs_are_never_modified() -> None:
    rng = np.random.default_rng(31)
    peaks = bench_peaks()
    kept_peaks = list(peaks)
    f = bench_frame(SHAPE, 0.0, rng=rng)
    kept = f.copy()
    demod = Demodulator(SHAPE, peaks, reference="synthetic", unwrap="always")
    demod.process(f)
    np.testing.assert_array_equal(f, kept)
    assert peaks == kept_peaks


def test_with_peaks_keeps_settings_and_recomputes_the_radius() -> None:
    demod = Demodulator(
        SHAPE, bench_peaks(), reference="absolute", wavelength=WAVELENGTH, window="tukey"
    )
    fewer = demod.with_peaks(bench_peaks()[:1])
    assert (fewer.reference, fewer.wavelength, fewer.window) == ("absolute", WAVELENGTH, "tukey")
    assert fewer.radii == tuple(auto_radii([bench_peaks()[0].carrier]))  # recomputed
    assert fewer.radii[0] > min(demod.radii)
    other = demod.with_peaks(bench_peaks(), reference="relative", radius=0.05)
    assert (other.reference, other.radius) == ("relative", 0.05)


def test_overlapping_windows_are_flagged() -> None:
    demod = Demodulator(SHAPE, bench_peaks(), radius=0.15)
    result = demod.process(bench_frame(SHAPE, 0.0, rng=np.random.default_rng(32)))
    assert all("overlap" in r.flags for r in result.peaks)


@pytest.mark.parametrize(
    ("peaks", "kwargs", "message"),
    [
        ([], {}, "no peaks"),
        ([Peak((0.7, 0.1), 0.1, 10.0)], {}, "outside the spectrum"),
        ([Peak((0.2, float("nan")), 0.1, 10.0)], {}, "non-finite"),
        ([Peak((0.2, 0.1), 0.1, 10.0, alpha=0.0)], {}, "alpha"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"radius": "widest"}, "'matched' or 'bound'"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"radius": 0.3}, "zero frequency"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"radius": -0.1}, "radius"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"window": "gauss"}, "unknown window"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"reference": "previous"}, "unknown reference"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"unwrap": "sometimes"}, "unknown unwrap"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"wavelength": -1.0}, "wavelength"),
        ([Peak((0.2, 0.1), 0.1, 10.0)], {"aperture": np.ones((3, 3), bool)}, "aperture"),
        (["RB1"], {}, "not a Peak"),
    ],
)
def test_bad_configurations(peaks: list, kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        Demodulator(SHAPE, peaks, **kwargs)


def test_a_given_radius_reaching_another_peak_is_used_with_a_warning(caplog) -> None:
    peaks = [Peak((0.2, 0.1), 0.1, 10.0, label="RB1"), Peak((0.25, 0.1), 0.1, 10.0, label="RF")]
    demod = Demodulator(SHAPE, peaks, radius=0.08)
    assert demod.radii == (0.08, 0.08)
    assert [w.rule for w in demod.windows] == ["given", "given"]
    assert len(demod.notes) == 2
    assert "around RB1 reaches RF (spacing 0.05)" in demod.notes[0]
    assert all(line in caplog.text for line in demod.notes)
    # an unselected neighbour is named by its carrier
    alone = Demodulator(SHAPE, peaks[:1], radius=0.08, neighbours=[(0.25, 0.1)])
    assert alone.notes and "the unselected peak at (0.25, 0.1)" in alone.notes[0]
    # the bound reaches nothing: no warning
    assert not Demodulator(SHAPE, peaks, radius="bound").notes


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (np.zeros((128, 128)), "expects"),
        (np.zeros(256), "2-D"),
        (np.zeros((256, 256, 3)), "2-D"),
        (np.zeros(SHAPE, complex), "dtype"),
    ],
)
def test_bad_frames(bad: np.ndarray, message: str) -> None:
    demod = Demodulator(SHAPE, bench_peaks())
    with pytest.raises(InputError, match=message):
        demod.process(bad)


def test_upsample_checks_the_shape() -> None:
    demod = Demodulator(SHAPE, bench_peaks())
    with pytest.raises(InputError, match="box resolution"):
        demod.upsample(np.zeros((5, 5)))


def test_refine_carriers_removes_the_residual_tilt() -> None:
    rng = np.random.default_rng(33)
    shape = (256, 256)
    before, after = [], []
    for _ in range(6):
        carrier = (rng.uniform(0.1, 0.4), rng.uniform(-0.4, 0.4))
        f = frame(shape, [carrier], [0.05], [rng.uniform(0, 6)], rng=rng)
        found = find_peaks(f, refine=False)[0].relabelled("X", alpha=1.0)
        assert found.carrier_error is None
        refined = refine_carriers(f, [found])[0]
        assert (refined.label, refined.alpha, refined.amplitude) == ("X", 1.0, found.amplitude)
        assert refined.carrier_error is not None and refined.carrier_error < 0.05
        assert find_peaks(f)[0].carrier == pytest.approx(refined.carrier, abs=1e-9)
        before.append(np.hypot(*(np.subtract(found.carrier, carrier) * shape)))
        after.append(np.hypot(*(np.subtract(refined.carrier, carrier) * shape)))
    assert max(after) < 0.01  # bins
    assert np.mean(after) < np.mean(before) / 2


@pytest.mark.parametrize("reference", ["relative", "absolute", "synthetic"])
def test_a_demodulator_resumed_from_another_s_state_gives_its_maps(reference: str) -> None:
    """Values given from elsewhere drive the mean phases; a second demodulator that takes
    the reference frame and then the first's state gives the same maps, bit for bit."""
    rng = np.random.default_rng(4)
    # a level rising 60 nm a frame: the absolute and synthetic maps need their 2 pi offsets
    frames = [bench_frame(SHAPE, 60e-9 * k + bump(SHAPE, 40e-9, 30), rng=rng) for k in range(6)]
    own = Demodulator(SHAPE, bench_peaks(), reference=reference, wavelength=WAVELENGTH)
    computed = [own.process(f) for f in frames]
    values = [[r.carrier_value for r in c.peaks] for c in computed]
    whole = Demodulator(SHAPE, bench_peaks(), reference=reference, wavelength=WAVELENGTH)
    results = [whole.process(f, v) for f, v in zip(frames, values, strict=True)]
    for a, b in zip(results, computed, strict=True):  # given its own values: the same maps
        for r, e in zip(a.peaks, b.peaks, strict=True):
            np.testing.assert_array_equal(r.phase, e.phase)
    given = Demodulator(SHAPE, bench_peaks(), reference=reference, wavelength=WAVELENGTH)
    for f, v in zip(frames[:3], values[:3], strict=True):
        given.process(f, v)
    state = given.phase_state()
    resumed = Demodulator(SHAPE, bench_peaks(), reference=reference, wavelength=WAVELENGTH)
    start = {"relative": 2, "absolute": 0}.get(reference)
    if start is not None:  # the frame that holds the reference fields
        resumed.process(frames[start], values[start])
    resumed.restore_phase_state(state)
    for f, v, expected in zip(frames[3:], values[3:], results[3:], strict=True):
        got = resumed.process(f, v)
        for r, e in zip(got.peaks, expected.peaks, strict=True):
            np.testing.assert_array_equal(r.phase, e.phase)
            assert r.flags == e.flags and r.mean_phase_unwrapped == e.mean_phase_unwrapped
    with pytest.raises(InputError, match="3 carrier values given for 4 peaks"):
        whole.process(frames[0], values[0][:3])
