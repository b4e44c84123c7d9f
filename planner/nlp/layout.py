"""Named blocks of an NLP vector: the decision vector ``w``, the parameters ``p`` or the constraints ``g``.

A vector is laid out as an ordered list of named blocks, each with its size and (for ``w`` and ``g``) its
lower and upper bounds. Code asks for ``layout.slice("tracking_rates")`` instead of adding up offsets; the
bounds are concatenated in the same order as the blocks, so the vector and its bounds never drift apart.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


class LayoutError(KeyError):
    """A block name asked for that the layout does not hold (``name``), or a block added twice."""

    def __init__(self, name: str, problem: str) -> None:
        self.name = name
        super().__init__(f"block {name!r}: {problem}")


@dataclass(frozen=True)
class Block:
    """One named block: where it sits in the vector and its bounds (each ``(size,)``)."""

    name: str
    start: int
    size: int
    lower: Array
    upper: Array

    @property
    def slice(self) -> slice:
        """The block's indices in the vector."""
        return slice(self.start, self.start + self.size)


class VectorLayout:
    """An ordered list of named blocks; optionally with each block's symbolic expression (a ``g`` vector)."""

    def __init__(self) -> None:
        self._blocks: dict[str, Block] = {}
        self._expressions: list[ca.MX] = []
        self.size = 0

    def add(self, name: str, size: int, lower: ArrayLike = -np.inf, upper: ArrayLike = np.inf,
            expression: ca.MX | None = None) -> slice:
        """Append block ``name`` of ``size`` entries with its bounds (scalars broadcast); its slice."""
        if name in self._blocks:
            raise LayoutError(name, "added twice")
        block = Block(name, self.size, int(size), _bounds(lower, size, name), _bounds(upper, size, name))
        self._blocks[name] = block
        if expression is not None:
            self._expressions.append(expression)
        self.size += block.size
        return block.slice

    def add_expression(self, name: str, expression: ca.MX, lower: ArrayLike = -np.inf,
                       upper: ArrayLike = np.inf) -> slice:
        """Append a constraint block: ``expression`` with its bounds (its size is the expression's)."""
        return self.add(name, expression.numel(), lower, upper, expression)

    def block(self, name: str) -> Block:
        """The block ``name``."""
        if name not in self._blocks:
            raise LayoutError(name, f"not in the layout (blocks: {', '.join(self._blocks)})")
        return self._blocks[name]

    def slice(self, name: str) -> slice:
        """Indices of block ``name`` in the vector."""
        return self.block(name).slice

    def __contains__(self, name: str) -> bool:
        return name in self._blocks

    def __iter__(self) -> Iterator[Block]:
        return iter(self._blocks.values())

    @property
    def lower(self) -> Array:
        """Lower bounds of the whole vector, block by block ``(size,)``."""
        return np.concatenate([b.lower for b in self] or [np.zeros(0)])

    @property
    def upper(self) -> Array:
        """Upper bounds of the whole vector, block by block ``(size,)``."""
        return np.concatenate([b.upper for b in self] or [np.zeros(0)])

    def expression(self) -> ca.MX:
        """The blocks' expressions stacked in order (a constraint vector ``g``)."""
        return ca.vertcat(*self._expressions)

    def pack(self, values: Mapping[str, ArrayLike]) -> Array:
        """One numeric vector from a value per block, in the layout's order (each flattened, sizes checked)."""
        parts = []
        for b in self:
            part = np.asarray(values[b.name], dtype=float).ravel()
            if part.size != b.size:
                raise LayoutError(b.name, f"expected {b.size} values, got {part.size}")
            parts.append(part)
        return np.concatenate(parts)


def _bounds(value: ArrayLike, size: int, name: str) -> Array:
    """``value`` as a ``(size,)`` float array (a scalar broadcast)."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(int(size), float(arr))
    arr = arr.ravel()
    if arr.size != size:
        raise LayoutError(name, f"{arr.size} bounds for {size} entries")
    return arr
