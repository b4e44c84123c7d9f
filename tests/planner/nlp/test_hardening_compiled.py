"""A broken compiled-Function cache is rebuilt, not interpreted forever (planner.nlp.compiled)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from planner.nlp import compiled as compiled_module
from planner.nlp.compiled import compiled


def _function(scale: float = 1.0) -> ca.Function:
    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p", 2)
    y = ca.vertcat(scale * ca.sin(x[0]) * p[0] + x[1] ** 3, ca.exp(x[2] * p[1]) / (1 + x[0] ** 2))
    return ca.Function("hard", [x, p], [y], ["x", "p"], ["y"])


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("LUTGEN_CACHE_DIR", str(folder))
    monkeypatch.setenv("LUTGEN_COMPILE", "1")
    monkeypatch.setattr(compiled_module, "fallback_reasons", [])
    return folder


def _break(library, damage: str, impostor) -> None:
    if damage == "truncated":  # e.g. a disk that filled up while the library was written
        library.write_bytes(library.read_bytes()[:200])
    else:  # another formula's library under this one's name (a copied cache)
        library.write_bytes(impostor.read_bytes())


@pytest.mark.parametrize("damage", ["truncated", "impostor"])
def test_a_broken_cached_library_is_compiled_again(cache, monkeypatch, damage):
    monkeypatch.setenv("LUTGEN_CACHE_DIR", str(cache.parent / "other"))
    compiled(_function(scale=3.0))
    impostor = next((cache.parent / "other").glob("hard-*.so"))
    monkeypatch.setenv("LUTGEN_CACHE_DIR", str(cache))
    compiled(_function())
    library = next(cache.glob("hard-*.so"))
    _break(library, damage, impostor)
    g = compiled(_function())
    assert g.is_a("External"), compiled_module.fallback_reasons
    assert compiled_module.fallback_reasons == []
    x, p = np.array([0.3, -0.2, 0.5]), np.array([1.5, -0.4])
    np.testing.assert_array_equal(np.asarray(g(x, p)), np.asarray(_function()(x, p)))
