"""Demodulation and analysis: pure numpy, pyFFTW, SciPy and scikit-image.

No Qt, no files, no threads (import-linter contracts enforce the first two). The
sub-packages are layers, each using only those listed before it (a contract enforces
the order); read them in this order:

1. :mod:`~holoview.processing.fourier`: planned FFTs, the frame checks, the spectral
   windows and the demodulation boxes, the display spectrum.
2. :mod:`~holoview.processing.peaks`: carrier peaks of a spectrum (detection, sub-bin
   carriers, snapping a carrier to a peak, each peak's window radius).
3. :mod:`~holoview.processing.maps`: per-frame maps (demodulation, spatial unwrapping,
   phase to height, co-registration and fusion).
4. :mod:`~holoview.processing.series`: the mean phase of every frame and what follows
   from it (the carrier probe, unwrapping in time, the joint estimate, depths, rates).
5. :mod:`~holoview.processing.naming` and :mod:`~holoview.processing.waves`: which
   family each peak is (the carrier lattice, the PCA), and the wave analyses of
   height maps over time.
"""

import sys


def _import_pyfftw() -> None:
    """Import pyFFTW without its Dask interface (every process starts 1-2 s sooner).

    pyFFTW's ``interfaces`` package imports ``dask.array`` whenever Dask is installed,
    to offer FFTs of Dask arrays, which holoview never uses: that import took 1.4-1.9 s
    of each ``holoview`` command and worker (2-core box). Dask is hidden for that one
    import and visible again after it; a process that imported Dask before is left as
    it is.
    """
    if "pyfftw" in sys.modules or "dask" in sys.modules:
        return
    sys.modules["dask"] = None  # type: ignore[assignment]  # "import dask" fails here
    try:
        import pyfftw  # noqa: F401
    finally:
        del sys.modules["dask"]


_import_pyfftw()
