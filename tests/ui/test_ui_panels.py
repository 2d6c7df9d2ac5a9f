"""Settings files, exports, and the source and recording panels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tifffile

from holoview.acquire.source import SettingInfo
from holoview.engine.experiment import config_dir
from holoview.errors import InputError
from holoview.live.session import RecordingProgress
from holoview.ui.exports import export_maps, export_window_png
from holoview.ui.recording_panel import RecordingPanel
from holoview.ui.settings import ui_settings
from holoview.ui.source_panel import SourcePanel

pytestmark = pytest.mark.gui


def test_ui_settings_live_under_xdg_config_home(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert config_dir() == tmp_path / "holoview"
    settings = ui_settings()
    settings.setValue("k", 1)
    settings.sync()
    assert (tmp_path / "holoview" / "ui.ini").is_file()


def test_export_maps_tif_and_npy(tmp_path: Path) -> None:
    maps = {"RB1": np.ones((4, 5)) * 1e-9, "fused": np.zeros((4, 5))}
    written = export_maps(maps, tmp_path / "snap.tif", "m")
    assert [p.name for p in written] == ["snap_RB1.tif", "snap_fused.tif"]
    assert np.allclose(tifffile.imread(written[0]), 1e-9)
    written = export_maps(maps, tmp_path / "snap.npy", "m")
    assert np.load(written[1]).shape == (4, 5)
    with pytest.raises(InputError, match=r"use \.tif or \.npy"):
        export_maps(maps, tmp_path / "snap.jpg", "m")
    with pytest.raises(InputError, match="no maps"):
        export_maps({}, tmp_path / "snap.npy", "m")


def test_export_window_png(qtbot, tmp_path: Path) -> None:
    panel = RecordingPanel(default_dir=tmp_path)
    qtbot.addWidget(panel)
    path = export_window_png(panel, tmp_path / "w")
    assert path.suffix == ".png" and path.read_bytes()[:4] == b"\x89PNG"


def test_recording_panel_request_and_indicator(qtbot, tmp_path: Path) -> None:
    panel = RecordingPanel(default_dir=tmp_path)
    qtbot.addWidget(panel)
    panel.limit_box.setCurrentIndex(2)
    panel.frames_spin.setValue(12)
    with qtbot.waitSignal(panel.startRequested) as blocker:
        panel.toggle()
    request = blocker.args[0]
    assert request.frames == 12 and request.duration_s is None
    assert request.path == tmp_path / "recording.h5"
    panel.set_progress(RecordingProgress(request.path, 5, 0.2, 1, True))
    assert (
        panel.recording
        and "REC" in panel.indicator.text()
        and "1 dropped" in panel.indicator.text()
    )
    assert not panel.path_edit.isEnabled()
    with qtbot.waitSignal(panel.stopRequested):
        panel.toggle()


def test_source_panel_disables_what_the_source_cannot_honour(qtbot) -> None:
    panel = SourcePanel()
    qtbot.addWidget(panel)
    infos = {
        "exposure_s": SettingInfo("exposure_s", "float", "s", (1e-5, 1.0), 1e-5),
        "frame_rate_hz": SettingInfo("frame_rate_hz", "float", "Hz", (1.0, 200.0), 0.1),
        "pixel_format": SettingInfo(
            "pixel_format", "enum", choices=("Mono8", "Mono16"), locked_while_streaming=True
        ),
        "roi": SettingInfo("roi", "roi", "pixel"),
        "temperature_k": SettingInfo("temperature_k", "float", "K", read_only=True),
    }
    values = {
        "exposure_s": 2e-3,
        "frame_rate_hz": 60.0,
        "pixel_format": "Mono16",
        "roi": (0, 0, 256, 256),
        "temperature_k": 300.0,
    }
    panel.set_settings(infos, values)
    assert panel.editor("exposure_s").value() == pytest.approx(2.0)  # shown in ms
    assert panel.editor("exposure_s").suffix() == " ms"
    assert not panel.editor("gain_db").isEnabled()  # the source has no gain
    assert not panel.editor("temperature_k").isEnabled()
    assert panel.editor("pixel_format").isEnabled()
    panel.set_streaming(True)
    assert not panel.editor("pixel_format").isEnabled()
    assert panel.editor("exposure_s").isEnabled()
    requested = []
    panel.settingRequested.connect(lambda n, v: requested.append((n, v)))
    panel.editor("exposure_s").setValue(5.0)
    assert requested == [("exposure_s", pytest.approx(5e-3))]
    panel.show_values({"exposure_s": 4.99e-3})  # the value read back, not the one asked for
    assert panel.editor("exposure_s").value() == pytest.approx(4.99)
    assert len(requested) == 1
