"""Seeing what a writer has flushed since a file was opened, without breaking other readers.

:meth:`h5py.Dataset.refresh` (``H5Drefresh``) re-reads a dataset's metadata so that a
SWMR reader sees the frames a writer flushed since. HDF5 shares one open file, and
one open dataset, between all the handles a process opens on them; a refresh of a
read-only dataset while a second handle of this process has the same dataset open
leaves it broken: from then on every chunk, through either handle, reads as the first
one (HDF5 2.0.0 with h5py 3.16, for a file being written and for a closed one alike;
only closing the other handle mends it). A replay refreshes its file at each end,
while the window's whole-run measurement reads the same file: the replay's next pass
then showed the first frame's pixels under advancing frame numbers.

So :func:`refresh_datasets` refreshes only where it can show something new and harms
nobody: the file is open for SWMR reading (a writer had it open; a file closed by its
writer never grows) and none of the datasets is open elsewhere in this process.
Otherwise they are left as they are; a later call, once the other handle has gone,
sees the growth.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import h5py
from h5py import h5f, h5i

__all__ = ["open_elsewhere", "refresh_datasets"]

logger = logging.getLogger(__name__)


def open_elsewhere(dataset: h5py.Dataset) -> bool:
    """True when another handle of this process has ``dataset`` open too.

    Datasets are matched by their path in the file (:func:`~holoview.acquire.hdf5_members.
    open_member` opens hard links only, so a path names one object).
    """
    file_id = h5i.get_file_id(dataset.id)
    name = h5i.get_name(dataset.id)
    ids = h5f.get_obj_ids(file_id, h5f.OBJ_DATASET)
    return sum(1 for other in ids if h5i.get_name(other) == name) > 1


def refresh_datasets(file: h5py.File, datasets: Sequence[h5py.Dataset]) -> bool:
    """Refresh ``datasets`` of ``file`` where that is safe and useful (module docstring).

    Parameters
    ----------
    file : h5py.File
        The open file the datasets belong to.
    datasets : sequence of h5py.Dataset
        Refreshed in the order given.

    Returns
    -------
    bool
        True when they were refreshed; False for a file no writer had open, or when one
        of them is open elsewhere in this process (a refresh would break its reads).
    """
    if not file.swmr_mode:
        return False
    busy = [d.name for d in datasets if open_elsewhere(d)]
    if busy:
        logger.debug("%s: %s open elsewhere in this process; not refreshed", file.filename, busy)
        return False
    for dataset in datasets:
        dataset.refresh()
    return True
