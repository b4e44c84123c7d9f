"""The ``lutgen`` command line: commands, exit codes, one-line errors."""
