"""holoview: multiplexed off-axis digital holography of fluid surfaces.

Subpackages
-----------
optics
    The paper's forward model: carriers, amplitudes and prefactors of every
    hologram family, image synthesis and numerical phase tracing.
processing
    Demodulation, peak finding, unwrapping, heights, identification and trends.
acquire
    Camera sources, the frame ring, the HDF5 recording format and recorder.
ui
    The Qt interface (the only package that imports Qt).
api
    The commands as Python functions: simulate, open a recording (lazy frames), process,
    open results as xarray, export (no Qt).
"""

__version__ = "0.1.0"
