"""Headless processing of a recording: the offline replay and test mode of docs/design.md.

The same processing as the GUI (:mod:`holoview.processing`), with no display, in a
plain loop over the frames of a file, usable from scripts and on a server.
:func:`holoview.headless.run.process_file` runs it all (``holoview process`` calls it);
the pieces:

- :mod:`~holoview.headless.inputs` opens the input (a holoview recording, a TIFF
  stack, a folder of images or a video) and settles the optics and the frame times
  from the file and the user's options;
- :mod:`~holoview.headless.selection` chooses the peaks to demodulate: from a JSON
  file, from two labels and the model, or the N strongest identified by PCA;
- :mod:`~holoview.headless.run_passes` says which passes a run makes over its frames:
  :mod:`~holoview.headless.frame_passes` streams them through the engine (the carrier
  probe for the series, the maps step for the displacements and the maps), read ahead
  by :mod:`~holoview.headless.reader` (memory bounded by a few frames), into a
  :mod:`~holoview.headless.run_data` record;
- :mod:`~holoview.headless.analysis` names the peaks (PCA), converts to depths, fuses
  them and fits the rates;
- :mod:`~holoview.headless.settings` holds how a run demodulates, and
  :mod:`~holoview.headless.run` runs it all;
- :mod:`~holoview.headless.parallel`: the frames on many cores or a Dask cluster
  (chunks measured in workers, stitched in order here, the results those of one
  process);
- :mod:`~holoview.headless.results`: what a run writes (``trends.csv``,
  ``summary.json``, ``results.h5`` in netCDF-4/CF, ``report.png``), how ``results.h5``
  is read back as xarray, and the exports (NetCDF, Zarr, MATLAB, TIFF stacks);
- :mod:`~holoview.headless.batch` processes a folder or a glob of recordings into a
  folder each, with ``index.csv`` of their rates.

No Qt here (an import-linter contract enforces it).
"""
