"""Camera sources, the frame ring, the HDF5 recording format and the recorder. No Qt."""
