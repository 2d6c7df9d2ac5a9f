"""The paper's forward model: setups, hologram families, image synthesis, phase tracing.

No Qt and no file I/O (an import-linter contract enforces both).
"""
