"""Carrier peaks of a hologram's spectrum.

Read in this order: :mod:`.detection` (the :class:`~.detection.Peak` record and
``find_peaks``), :mod:`.carriers` (carriers below one FFT bin), :mod:`.snapping` (one
rule for naming the detected peak nearest a carrier), :mod:`.radii` (the checks of the
peaks to demodulate and each one's window radius).
"""
