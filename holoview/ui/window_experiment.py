"""The main window's experiment: labels, window radius, reference mode, the experiment file.

A mixin of :class:`~holoview.ui.main_window.MainWindow`: the operator's labelling
actions (a click named in the spectrum, the labels a source suggests, a label
cleared), the radius and the reference mode go into the window's
:class:`~holoview.engine.experiment.Experiment`, to the live session, to the whole
run's trends of a replayed file (measured again for new labels), and to the
experiment file, which is saved at each change. A recording opened carries the
experiment it was made with: it is applied as ``holoview process`` applies it, and a
notice offers the one click back to the labels in force before.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from PyQt6.QtWidgets import QFileDialog, QWidget

from holoview.engine.experiment import Experiment, LabelledPeak
from holoview.errors import HoloviewError

if TYPE_CHECKING:
    from holoview.live.maps_pipeline import LiveResult
    from holoview.live.session import LiveSession
    from holoview.ui.notice_bar import NoticeBar
    from holoview.ui.run_trends import RunTrends
    from holoview.ui.spectrum_view import SpectrumView
    from holoview.ui.status_bar import LiveStatusBar
    from holoview.ui.surface_view import SurfaceView

#: The experiment's optical fields, which a source or the command line may know better.
OPTICS_FIELDS = ("wavelength_m", "pixel_pitch_m", "n1", "n2")


#: Added to the name of an experiment file the window could not read, for its own settings.
IGNORED_SUFFIX = ".window.json"


class ExperimentActions:
    """The experiment part of the main window (mixed into it; no state of its own)."""

    experiment: Experiment
    experiment_path: Path
    optics: dict[str, float]
    session: LiveSession | None
    spectrum: SpectrumView
    surface: SurfaceView
    status: LiveStatusBar
    notice: NoticeBar
    run_trends: RunTrends
    _known: tuple[Experiment, str] | None
    _last_result: LiveResult | None
    _previous_experiment: Experiment | None
    show_message: Callable[[str], None]

    def _dialog_parent(self) -> QWidget | None:
        """The window this part is mixed into, as the parent of its dialogs."""
        return self if isinstance(self, QWidget) else None

    def _set_experiment(self, experiment: Experiment) -> None:
        self.experiment = experiment
        if self.session is not None:
            self.session.set_experiment(experiment)
            if self.session.replay is not None:
                self.session.replay.show_again()  # paused, the frame shown gets the new labels
        self.run_trends.set_experiment(experiment)
        self._offer_known_labels()
        try:
            experiment.save(self.experiment_path)
        except OSError as exc:
            self.show_message(f"cannot save experiment settings to {self.experiment_path}: {exc}")

    def _apply_recording_experiment(self, stored: Experiment | None, setup: dict[str, Any]) -> None:
        """Use the experiment a replayed recording carries, as ``holoview process`` does.

        Its labels and demodulation settings; the optics the command line gave, else
        the recording's setup, else its own. A notice says so, with the click back to
        the labels in force before.
        """
        if stored is None or not stored.peaks:
            self.notice.dismiss()
            return
        optics: dict[str, Any] = {k: float(setup[k]) for k in OPTICS_FIELDS if k in setup}
        optics |= {k: v for k, v in self.optics.items() if k in OPTICS_FIELDS}
        try:
            applied = replace(stored, **optics)
        except HoloviewError as exc:
            self.show_message(f"the recording's experiment is not usable: {exc}")
            return
        if applied == self.experiment:
            self.notice.dismiss()
            return
        self._previous_experiment = self.experiment
        self._set_experiment(applied)
        self.surface.set_reference(applied.reference)
        names = ", ".join(p.label for p in applied.peaks)
        self.notice.show_notice(
            f"Using the experiment the recording carries, as holoview process does: "
            f"{names}; {applied.reference} reference.",
            "Back to the labels before",
            self.restore_previous_experiment,
        )

    def restore_previous_experiment(self) -> None:
        """Go back to the labels and settings in force before a recording's were applied.

        The optics stay the recording's (they describe its frames).
        """
        previous = self._previous_experiment
        if previous is None:
            return
        self._previous_experiment = None
        optics: dict[str, Any] = {k: getattr(self.experiment, k) for k in OPTICS_FIELDS}
        self._set_experiment(replace(previous, **optics))
        self.surface.set_reference(previous.reference)
        labels = ", ".join(p.label for p in previous.peaks) or "none"
        self.status.showMessage(f"back to the labels before: {labels}", 6000)

    def _learn_known_labels(self) -> None:
        """Ask the new source which labels it knows (simulator, recording)."""
        try:
            self._known = self.session.known_experiment() if self.session else None
        except HoloviewError as exc:
            self._known = None
            self.show_message(f"no labels to suggest: {exc}")
        self._offer_known_labels()

    def _offer_known_labels(self) -> None:
        """Draw the known labels on the spectrum while no peak is labelled."""
        offer = self._known if self._known and self._known[0].peaks else None
        if offer is None or self.experiment.peaks:
            self.spectrum.set_suggestions({})
            return
        experiment, where = offer
        self.spectrum.set_suggestions({p.label: p.carrier for p in experiment.peaks}, where)

    def use_known_labels(self) -> None:
        """Label the peaks the source knows (the spectrum's "Use these labels")."""
        if not self._known or not self._known[0].peaks:
            self.show_message("this source suggests no labels: click a peak to name it")
            return
        experiment, where = self._known
        self._set_experiment(replace(self.experiment, peaks=experiment.peaks))
        names = ", ".join(p.label for p in experiment.peaks)
        self.status.showMessage(f"labelled {names} from {where}", 6000)

    def suggested_labels(self) -> list[tuple[str, float, float]]:
        """Return ``(label, fx, fy)`` to label, for scripted runs.

        The labels the source knows (the simulator's true RF, RB1 and FB1, a recording's
        stored labels); otherwise the two brightest detected peaks as RB1 and FB1, the
        brightest taken as RB1 (the paper's procedure). Fewer than two when fewer peaks
        were detected.
        """
        if self._known and self._known[0].peaks:
            return [(p.label, *p.carrier) for p in self._known[0].peaks]
        peaks = self._last_result.peaks[:2] if self._last_result else []
        return [(name, *c) for name, c in zip(("RB1", "FB1"), peaks, strict=False)]

    def label_peak(self, label: str, fx: float, fy: float) -> None:
        """Name the peak at ``(fx, fy)`` cycles per pixel ``label``."""
        self._set_experiment(self.experiment.with_peak(LabelledPeak(label, (fx, fy))))
        self.status.showMessage(f"labelled {label} at ({fx:+.4f}, {fy:+.4f}) cycles/px", 4000)

    def clear_label(self, label: str) -> None:
        """Forget the peak named ``label``."""
        self._set_experiment(self.experiment.without_label(label))

    def set_radius(self, radius: float) -> None:
        """Use window radius ``radius`` cycles per pixel."""
        try:
            self._set_experiment(replace(self.experiment, radius=radius))
        except HoloviewError as exc:
            self.show_message(str(exc))

    def set_reference(self, mode: str) -> None:
        """Use reference mode ``mode`` (relative, absolute, synthetic)."""
        try:
            self._set_experiment(replace(self.experiment, reference=mode))
        except HoloviewError as exc:
            self.show_message(str(exc))

    def _load_experiment_at_start(self) -> str | None:
        problem = None
        if self.experiment_path.exists():
            try:
                self.experiment = Experiment.load(self.experiment_path)
            except HoloviewError as exc:
                # the file is the user's: kept as it is, the window's settings saved beside
                ignored = self.experiment_path
                self.experiment_path = ignored.with_name(ignored.name + IGNORED_SUFFIX)
                problem = (
                    f"experiment settings ignored: {exc} (the file is kept; this window's "
                    f"settings are saved to {self.experiment_path})"
                )
        try:
            self.experiment = self.experiment.with_optics(self.optics)
        except HoloviewError as exc:
            problem = f"optics options ignored: {exc}"
            self.optics = {}
        return problem

    def load_experiment(self, path: Path) -> None:
        """Read experiment settings from ``path`` and use them."""
        try:
            experiment = Experiment.load(path)
        except HoloviewError as exc:
            self.show_message(str(exc))
            return
        self._set_experiment(experiment)
        self.surface.set_reference(experiment.reference)

    def load_experiment_dialog(self) -> None:
        """Ask for an experiment settings file and load it."""
        path, _ = QFileDialog.getOpenFileName(
            self._dialog_parent(), "Load experiment settings", "", "JSON (*.json)"
        )
        if path:
            self.load_experiment(Path(path))

    def save_experiment_dialog(self) -> None:
        """Ask where to save the experiment settings."""
        path, _ = QFileDialog.getSaveFileName(
            self._dialog_parent(),
            "Save experiment settings",
            str(self.experiment_path),
            "JSON (*.json)",
        )
        if path:
            try:
                self.experiment.save(Path(path))
            except OSError as exc:
                self.show_message(f"cannot save {path}: {exc}")
