"""Per-frame maps: demodulation, unwrapping, heights, co-registration and fusion.

Read in this order: :mod:`.demodulate` (the ``Demodulator``: one FFT a frame, a box a
peak), :mod:`.demod_results` (what it returns), :mod:`.phase_maps` and :mod:`.unwrap`
(phase maps, spatial unwrapping, masks and noise), :mod:`.heights` (phase to height and
the fusion of maps), :mod:`.coregister` (the maps' measured displacements).
"""
