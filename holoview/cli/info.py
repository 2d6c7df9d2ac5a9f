"""``holoview info``: versions of everything holoview runs on, and the Aravis status."""

from __future__ import annotations

import argparse
import importlib
import platform
import sys

from holoview.cli.signals import emit


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Register ``info``."""
    return subparsers.add_parser(
        "info", help="print library versions and whether GenICam (Aravis) is usable"
    )


def _module_version(name: str, attribute: str = "__version__") -> str:
    try:
        module = importlib.import_module(name)
    except ImportError as exc:
        return f"not importable ({exc})"
    return str(getattr(module, attribute, "unknown"))


def qt_versions() -> tuple[str, str]:
    """Return (Qt runtime version, PyQt6 version), or a reason in both when absent."""
    try:
        from PyQt6.QtCore import PYQT_VERSION_STR, qVersion
    except ImportError as exc:
        reason = f"not importable ({exc})"
        return reason, reason
    return qVersion() or "unknown", PYQT_VERSION_STR


def aravis_status() -> tuple[bool, str]:
    """Return whether Aravis imports through PyGObject, with its version or the reason not."""
    try:
        import gi
    except ImportError as exc:
        return False, (
            f"PyGObject is not installed ({exc}); GenICam cameras need Aravis 0.8 and "
            "GObject introspection from the system, then pip install 'holoview[genicam]' "
            "(on Debian 12 as root: scripts/setup.sh)"
        )
    try:
        gi.require_version("Aravis", "0.8")
        from gi.repository import Aravis
    except (ImportError, ValueError) as exc:
        return False, f"the Aravis 0.8 typelib is missing ({exc}); install gir1.2-aravis-0.8"
    interfaces = Aravis.get_n_interfaces()  # the first call loads the shared library
    return True, (
        f"Aravis {_loaded_aravis_version()} through PyGObject {gi.__version__}, "
        f"{interfaces} interfaces"
    )


def _loaded_aravis_version() -> str:
    """Return the version in the file name of the libaravis this process loaded."""
    try:
        with open("/proc/self/maps", encoding="ascii", errors="replace") as maps:
            for line in maps:
                name = line.rsplit("/", 1)[-1].strip()
                if name.startswith("libaravis-") and ".so." in name:
                    return name.split(".so.", 1)[1]
    except OSError:
        pass
    return "0.8"


def run(args: argparse.Namespace) -> int:
    """Print one ``name: version`` line per component (OutputError when stdout fails)."""
    from holoview import __version__

    qt, pyqt = qt_versions()
    cv2_version = _module_version("cv2")
    usable, aravis = aravis_status()
    rows = [
        ("holoview", __version__),
        ("Python", f"{platform.python_version()} ({sys.executable})"),
        ("Qt", qt),
        ("PyQt6", pyqt),
        ("pyqtgraph", _module_version("pyqtgraph")),
        ("numpy", _module_version("numpy")),
        ("pyFFTW", _module_version("pyfftw")),
        ("h5py", _module_version("h5py")),
        ("OpenCV", cv2_version),
        ("scikit-image", _module_version("skimage")),
        ("tifffile", _module_version("tifffile")),
        ("matplotlib", _module_version("matplotlib")),
        ("GenICam (Aravis)", ("yes: " if usable else "no: ") + aravis),
    ]
    width = max(len(name) for name, _ in rows)
    emit("\n".join(f"{name:<{width}}  {value}" for name, value in rows))
    return 0
