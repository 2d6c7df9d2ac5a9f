"""The wave analyses of a run's height maps, headless: ``holoview waves`` and ``process --waves``.

The analyses themselves are Qt-free functions of :mod:`holoview.processing.waves`; here
they are run over a ``results.h5`` (the maps step's maps, results.h5 2.x layout) a block
of frames at a time, so memory stays a segment's whatever the length. Read in this order:

- :mod:`.maps`: one label's maps, their pixel size, frame times (gaps kept) and the
  window's wavenumber cut-off, read a block at a time (relative maps summed into heights);
- :mod:`.tones`: the tones of E(omega), where the centre and the modes are sought;
- :mod:`.analysis`: :class:`~.analysis.WaveOptions` and :func:`~.analysis.analyse_waves`,
  the passes over the frames (omega-k, E(k), E(omega), the dispersion fit; the centre,
  the (m, f) spectrum, partial waves, ringdown, lock-ins) into a
  :class:`~.analysis.WaveResults`;
- :mod:`.figures`: the PNG figures, axes in physical units;
- :mod:`.outputs`: :func:`~.outputs.run_waves`, which writes ``waves.h5``,
  ``waves.json`` and the figures into an output folder (complete files or none).

No Qt here (an import-linter contract enforces it).
"""
