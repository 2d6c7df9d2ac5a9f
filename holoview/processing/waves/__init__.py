"""Waves on the surface, from height maps over time: spectra, dispersion, partial waves.

Every analysis takes maps ``h(t, y, x)`` in metres with NaN where untrusted, their true
frame times and their pixel size, and streams: an accumulator takes maps a frame (or a
block) at a time, so memory stays bounded whatever the length of the record, and a live
view can ask for the spectrum of the last segment. Sign convention:
:data:`.omega_k.SIGN_CONVENTION` (``exp(-i omega t)``; power at ``(f, +k)`` travels
along ``+k``).

Read in this order: :mod:`.clock` (frame times, gaps, runs), :mod:`.omega_k` (the
Welch omega-k spectrum, E(k), E(omega)), :mod:`.dispersion` (the capillary-gravity
relation with a flow, its fit of sigma, d and U; :mod:`.fit_text` writes its values with
their errors), :mod:`.azimuthal` (rings around a
centre, the (m, f) spectrum, radial profiles), :mod:`.centre` (the centre found, its
error), :mod:`.partial_waves`
(incoming and outgoing Hankel parts), :mod:`.ringdown` (a damped mode in one band),
:mod:`.lockin` (amplitude and phase maps at a drive frequency), :mod:`.filters` (band
filters giving filtered maps).
"""
