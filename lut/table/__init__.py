"""The look-up table's data: grid and its symmetries, the HDF5 store, the crash-safe journal, per-point records."""
