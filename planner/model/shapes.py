"""Convex collision primitives attached to bodies: boxes and capsules (paper §4.4).

A shape is placed in its parent body's frame by ``T_body_shape`` (4×4 homogeneous, metres).
A capsule is the segment from ``-length/2`` to ``+length/2`` along the shape frame's z axis,
swept by a sphere of ``radius``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Box:
    """Axis-aligned box in its shape frame, full side lengths ``size_m`` [m]."""

    size_m: tuple[float, float, float]

    def scaled(self, factor: float) -> Box:
        """This box with every side multiplied by ``factor``."""
        return Box(tuple(factor * s for s in self.size_m))  # type: ignore[arg-type]


@dataclass(frozen=True)
class Capsule:
    """Capsule along the shape frame's z axis: segment length ``length_m`` [m], radius ``radius_m`` [m]."""

    radius_m: float
    length_m: float

    def scaled(self, factor: float) -> Capsule:
        """This capsule with its radius and length multiplied by ``factor``."""
        return Capsule(factor * self.radius_m, factor * self.length_m)


Shape = Box | Capsule


@dataclass(frozen=True)
class PlacedShape:
    """A shape rigidly attached to a body: ``T_body_shape`` is its pose in the body frame."""

    name: str
    shape: Shape
    T_body_shape: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))


def make_transform(R: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """4×4 homogeneous transform from a rotation matrix and a translation [m]."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T
