"""Waves on the surface, from height maps over time: spectra and dispersion."""
