"""Which family each peak is: the carrier lattice, confirmed by the PCA of the phases.

Read in this order: :mod:`.lattice_geometry` (every peak as two integers),
:mod:`.lattice` (identification by the lattice) with its parts :mod:`.lattice_search`,
:mod:`.lattice_brightness`, :mod:`.lattice_labels`, :mod:`.lattice_ghosts` and
:mod:`.lattice_pca`; :mod:`.labelling` (from two labelled peaks, every peak the model
explains); :mod:`.pca` and :mod:`.prefactors` (the PCA of the phases and its
prefactors); :mod:`.identify` (the lattice and the PCA together).
"""
