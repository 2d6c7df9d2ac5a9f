"""Demodulation and analysis: pure numpy, pyFFTW and scikit-image.

No Qt, no files, no threads (an import-linter contract enforces the first two).
"""
