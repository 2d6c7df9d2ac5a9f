"""Headless processing of a recording: the offline replay and test mode of DESIGN.md.

The same processing as the GUI (:mod:`holoview.processing`), with no display, in a
plain loop over the frames of a file, usable from scripts and on a server:

- :mod:`~holoview.headless.inputs` opens the input (a holoview recording, a TIFF
  stack, a folder of images or a video) and settles the optics and the frame times
  from the file and the user's options;
- :mod:`~holoview.headless.selection` chooses the peaks to demodulate: from a JSON
  file, from two labels and the model, or the N strongest identified by PCA;
- :mod:`~holoview.headless.pipeline` streams the frames through one
  :class:`~holoview.processing.demodulate.Demodulator` (memory bounded by a few frames)
  and turns the peak series into depths, rates and flags;
- :mod:`~holoview.headless.outputs` writes ``trends.csv``, ``summary.json`` and
  ``results.h5``, and :mod:`~holoview.headless.report` draws ``report.png``.

No Qt here: the report is drawn with OpenCV.
"""
