"""lutgen's look-up table: the table's data, the one-point solve, the build, the online query, the outputs, the CLI."""
