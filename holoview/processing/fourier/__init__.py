"""The Fourier layer: planned FFTs, frame checks, spectral windows, boxes.

Read in this order: :mod:`.fftplans` (pyFFTW plans and wisdom), :mod:`.frames` (can a
frame be demodulated?), :mod:`.spectrum` (a frame's spectrum and its display),
:mod:`.half_spectrum` (a frame's FFT, along the columns only where it is read),
:mod:`.windows` (radial windows and the automatic radius), :mod:`.resample` (box grid
and frame grid), :mod:`.boxes` (where each peak's box is cut from the half spectrum),
:mod:`.fastmath` (the phase of complex maps, fast).
"""
