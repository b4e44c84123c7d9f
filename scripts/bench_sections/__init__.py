"""The sections of ``scripts/bench.py``: one module per JSON section, shared helpers in :mod:`.common`."""

import sys
from pathlib import Path

# the sections that query or plan in process measure this checkout's code, not the one the environment installed (a
# frozen worktree run with another checkout's .venv measured that checkout's query until this)
_CHECKOUT = str(Path(__file__).resolve().parents[2])
if sys.path[:1] != [_CHECKOUT]:
    sys.path.insert(0, _CHECKOUT)
