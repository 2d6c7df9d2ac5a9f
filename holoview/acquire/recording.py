"""holoview's HDF5 recording format: its layout, name and versions.

Written by :class:`~holoview.acquire.recording_writer.RecordingWriter` (SWMR, followable
live), read by :class:`~holoview.acquire.recording_reader.RecordingReader`.

File layout, format ``holoview-recording`` version ``1.1``
----------------------------------------------------------
Everything is created before the writer switches the file to SWMR mode, so a
reader can open the file while it is being written and follow it with
:meth:`~holoview.acquire.recording_reader.RecordingReader.refresh`. The file is opened with
``libver=('v110', 'latest')``: HDF5 1.10 tools can read it, SWMR works.

``/`` (root) attributes
    ``format`` (str, always ``"holoview-recording"``), ``format_version`` (str,
    ``"MAJOR.MINOR"``; readers accept any minor version of a major version they
    know), ``uuid`` (str, RFC 4122, unique per recording), ``created_utc`` (str,
    ISO 8601 start time in UTC), ``source`` (str, the source specification or
    camera name the frames came from), ``holoview_version`` (str).
``/frames`` dataset, shape ``(n_frames, rows, cols)``
    The raw camera values in the camera's own dtype (``uint8`` or ``uint16``;
    Mono10/12/16 stay unscaled in 16-bit containers). Chunked one frame per chunk,
    uncompressed, growing along axis 0. Attributes: ``pixel_format`` (str, e.g.
    ``"Mono12"``) and ``significant_bits`` (int).
``/frame_id`` dataset, ``int64``, shape ``(n_frames,)``
    The camera's frame counter (gaps mean frames the camera or transport lost).
``/t_device_s`` dataset, ``float64``, shape ``(n_frames,)``, seconds
    The camera's timestamp, on the camera's clock (``NaN`` where it has none).
``/t_host_s`` dataset, ``float64``, shape ``(n_frames,)``, seconds
    When the host received the frame, seconds since the UNIX epoch (``time.time()``).
``/setup`` group
    The optical setup as attributes: ``wavelength_m`` (m), ``pixel_pitch_m`` (m),
    ``n1`` and ``n2`` (refractive indices of the media above and below the surface,
    dimensionless), and anything else the writer was given. The unit of each
    attribute is the attribute of the same name on ``/setup/units`` (``""`` for
    dimensionless).
``/settings`` group
    Every camera setting at the start of the recording as attributes (for example
    ``exposure_s``, ``gain_db``, ``frame_rate_hz``, ``roi`` as
    ``(left, top, width, height)`` pixels), units on ``/settings/units`` the same way.
``/experiment`` group (since 1.1; absent when the writer was given none)
    The experiment in force (optics, labelled peaks, window, reference: the JSON of
    :mod:`holoview.engine.experiment`) and every change during the run. ``json`` is a
    ``uint8`` dataset holding the UTF-8 texts one after another; ``changes`` an
    ``int64`` dataset of shape ``(n_changes, 3)``: per change, the frame index it holds
    from, and the offset and length of its text in ``json``. Both grow while the file
    is written (SWMR has no variable-length strings).

A setting or setup value of ``None`` is not written. Names ending in a unit suffix
(``_m``, ``_s``, ``_hz``, ``_db``, ``_px``, ``_k``) get that unit unless one is
given explicitly. Other groups (for example ``/truth``, which the simulator adds by
reopening a closed recording with ``h5py.File(path, "a")``) are ignored by readers.

Durability: the writer flushes at most ``flush_interval_s`` (default 0.5 s) after
an append, and its ``flush_if_due`` lets an idle recorder keep that promise; a writer
killed at any moment leaves a file that opens with every frame up to its last flush.
A full disk ends a recording cleanly: the writer checks the free space before each
frame and raises :class:`~holoview.acquire.recording_writer.DiskFullError` while a
frame and the room to close the file still fit; when a write fails anyway (another
program filled the disk, an I/O error) it raises
:class:`~holoview.acquire.recording_writer.RecordingWriteError`, and its ``close``
gives back the reserve it keeps beside the file (:mod:`holoview.acquire.durability`),
trims the datasets to the frames fully written and closes the file, which plain h5py
and HDF5 tools then open.
Readers refuse a truncated file at once instead of retrying (same module).
"""

from __future__ import annotations

#: The value of the root ``format`` attribute.
FORMAT_NAME = "holoview-recording"
#: The format version written.
FORMAT_VERSION = "1.1"
#: Format major versions read.
SUPPORTED_MAJOR_VERSIONS = (1,)
#: HDF5 library version bounds: readable by HDF5 1.10, SWMR-capable.
LIBVER = ("v110", "latest")
