"""The labels an operator would set on a simulated bench: from the optics, not from a click.

``holoview simulate`` stores them in its recordings (so ``holoview process`` needs no
peak options) and the live window offers them on the simulated camera (one click,
"Use these labels"): one rule for both.
"""

from __future__ import annotations

from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.optics.families import Family, coherent_amplitude, predict_families
from holoview.optics.setup import Setup

#: A first-order family is labelled when its peak reaches this fraction of the mean
#: intensity (``holoview simulate``'s figure marks the same peaks).
VISIBLE_AMPLITUDE = 1e-3
#: The families labelled: two of them fix the carrier lattice, which names the rest.
TRUE_LABELS = ("RF", "RB1", "FB1")


def visible_amplitudes(setup: Setup, families: list[Family]) -> dict[str, float]:
    """Return each family's peak size: the coherent field sum for first orders.

    Pairs sharing a carrier add up (and cancel, at FB_j near a lossless mirror); a
    second-order peak keeps its own amplitude.
    """
    return {
        f.label: f.amplitude if f.kind == "second-order" else coherent_amplitude(setup, f.label)
        for f in families
    }


def true_experiment(
    setup: Setup,
    families: list[Family] | None = None,
    visible: dict[str, float] | None = None,
) -> Experiment:
    """The experiment an operator would set on this bench: its optics and true labels.

    RF, RB1 and FB1, where their peak is at least :data:`VISIBLE_AMPLITUDE` of the mean
    intensity, are labelled where the camera sees them (folded back when past
    Nyquist), on the twin whose phase grows with the height, as an operator labels
    them at alignment; the carrier lattice names the other families where they are
    detected (two of the three fix it).

    Parameters
    ----------
    setup : Setup
        The simulated bench.
    families, visible : optional
        :func:`~holoview.optics.families.predict_families` of ``setup`` and their
        :func:`visible_amplitudes`, when the caller has them already.
    """
    families = predict_families(setup) if families is None else families
    visible = visible_amplitudes(setup, families) if visible is None else visible
    peaks = tuple(
        LabelledPeak(f.label, f.observed_carrier)
        for f in families
        if f.label in TRUE_LABELS and visible[f.label] >= VISIBLE_AMPLITUDE
    )
    return Experiment(
        wavelength_m=setup.wavelength,
        pixel_pitch_m=setup.pixel_pitch,
        n1=setup.n1,
        n2=setup.n2,
        peaks=peaks,
    )
