"""The paper's forward model: setups, hologram families, image synthesis, phase tracing.

- :mod:`~holoview.optics.setup`: the bench and camera (:class:`Setup`, :data:`FLUIDS`).
- :mod:`~holoview.optics.beams`: the fields R, F, B_j and ghosts, their general sum.
- :mod:`~holoview.optics.families`: carriers, amplitudes, alpha and displacements of
  every hologram family; inferring carriers from two labelled peaks.
- :mod:`~holoview.optics.surfaces`: surfaces with a known truth, the dispersion relation.
- :mod:`~holoview.optics.synthesis` and :mod:`~holoview.optics.camera`: fast frames.
- :mod:`~holoview.optics.tracing`: the supplement's numerical phase tracing.
- :mod:`~holoview.optics.scenarios`: simulated sequences with their truth.

No Qt and no file I/O (an import-linter contract enforces both).
"""
