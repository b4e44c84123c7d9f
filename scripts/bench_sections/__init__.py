"""The sections of ``scripts/bench.py``: one module per JSON section, shared helpers in :mod:`.common`."""
