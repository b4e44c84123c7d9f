"""lutgen's look-up table: grid sweeps of the planner, the HDF5 store, queries, and the CLI."""
