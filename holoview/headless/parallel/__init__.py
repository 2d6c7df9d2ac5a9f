"""A run's frames on many processes or a Dask cluster, the results those of one process.

Read in this order: :mod:`.runners` (where chunks run: local worker processes or Dask,
:mod:`.dask_cluster` starting a local cluster or checking a scheduler),
:mod:`.chunks` (a run's frames in chunks, and what a worker does with one),
:mod:`.chunk_maps` (a chunk's maps, from the state the serial run holds at its start),
:mod:`.stitch` (the chunks taken in order: the series, the maps, what depends on order).
"""
