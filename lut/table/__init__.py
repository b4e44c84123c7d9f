"""The look-up table's data: the grid and its symmetries, typed point results and their flat records, the HDF5
store (schema, writer, reader) and the crash-safe build journal."""
