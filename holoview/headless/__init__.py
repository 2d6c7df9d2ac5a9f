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
- :mod:`~holoview.headless.pipeline` streams the frames through one
  :class:`~holoview.processing.maps.demodulate.Demodulator`, read ahead by
  :mod:`~holoview.headless.reader` (memory bounded by a few frames);
- :mod:`~holoview.headless.analysis` names the peaks (PCA), converts to depths, fuses
  them and fits the rates;
- :mod:`~holoview.headless.outputs` writes ``trends.csv``, ``summary.json`` and
  ``results.h5``, and :mod:`~holoview.headless.report` draws ``report.png`` (or PDF,
  SVG) with matplotlib on the Agg canvas of :mod:`~holoview.headless.figures`;
- on many cores or a Dask cluster: :mod:`~holoview.headless.chunks` splits the frames
  and measures a chunk's carrier values in a worker, :mod:`~holoview.headless.parallel`
  runs the chunks (local processes or Dask), :mod:`~holoview.headless.stitch` joins
  them in order with the maps and the series of the run;
- :mod:`~holoview.headless.results_layout` lays ``results.h5`` out as netCDF-4/CF
  (with the dimension-scale helpers of :mod:`~holoview.headless.cf`);
  :mod:`~holoview.headless.results_data` opens ``results.h5`` (formats 2.0 and 1.0) as
  xarray Datasets, and :mod:`~holoview.headless.exports` writes them as NetCDF, Zarr,
  MATLAB (:mod:`~holoview.headless.export_mat`) or TIFF stacks (``holoview export``);
- :mod:`~holoview.headless.batch` processes a folder or a glob of recordings into a
  folder each, with ``index.csv`` of their rates.

No Qt here (an import-linter contract enforces it).
"""
