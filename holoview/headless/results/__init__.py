"""What a run writes and how it is read back: the files, the report, the exports.

Read in this order: :mod:`.output_folder` (temporary names, put in place when a run
completes), :mod:`.outputs` (``trends.csv``, ``summary.json``, ``results.h5`` while a run
writes it), :mod:`.results_layout` and :mod:`.cf` (``results.h5``'s netCDF-4/CF layout),
:mod:`.report` and :mod:`.figures` (``report.png``), :mod:`.results_data` (``results.h5``
as xarray Datasets), :mod:`.exports` and :mod:`.export_mat` (``holoview export``).
"""
