"""Where the GUI keeps its own state: window geometry, dock layout, last folders.

That state belongs to one operator on one machine and lives in a
:class:`~PyQt6.QtCore.QSettings` INI file, ``$XDG_CONFIG_HOME/holoview/ui.ini``. The
experiment (optics, labelled peaks, window, reference) is not UI state: it is the
portable :class:`holoview.engine.experiment.Experiment`, kept in
:func:`~holoview.engine.experiment.default_experiment_path` between sessions and in
every recording.
"""

from __future__ import annotations

from PyQt6.QtCore import QSettings

from holoview.engine.experiment import config_dir


def ui_settings() -> QSettings:
    """Return the QSettings that hold the window layout (an INI file in the config folder)."""
    return QSettings(str(config_dir() / "ui.ini"), QSettings.Format.IniFormat)
