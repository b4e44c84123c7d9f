"""Tests of planner.collision.scene_distances against references independent of fcl.

References: hand-computed distances; the analytic segment–segment formula; for boxes, the separated
distance as a bounded linear least-squares problem (scipy ``lsq_linear``: closest points of two boxes /
a box and a segment are the minimiser of ``‖(c_a + R_a u) - (c_b + R_b v)‖`` over the box extents) and
the penetration depth by the separating-axis theorem (for polytopes the minimum-translation direction is a
face normal of the Minkowski difference: a face normal of either box or a cross product of edges).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.optimize import lsq_linear
from scipy.spatial.transform import Rotation

from planner.collision.layout import CollisionBody, default_pairs
from planner.collision.scene_distances import CollisionScene, PairDistance, distance_gradient
from planner.model.rotation import axis_angle_to_matrix, skew
from planner.model.shapes import Box, Capsule, PlacedShape, make_transform
from tests.support.distance_oracle import segment_closest_points

Array = NDArray[np.float64]
I3 = np.eye(3)
RX90 = axis_angle_to_matrix([1.0, 0.0, 0.0], np.pi / 2)  # maps the capsule axis z to y
RY90 = axis_angle_to_matrix([0.0, 1.0, 0.0], np.pi / 2)  # maps z to x
RZ45 = axis_angle_to_matrix([0.0, 0.0, 1.0], np.pi / 4)
# coal's GJK on box pairs lands ~1e-10 m off the exact distance whatever its tolerance: 1e4 below the 1e-6 m bar
BOX_TOL_M = 1e-9


# ----------------------------------------------------------------------------------------------- helpers
def closest_points_segment_segment(p0a, p1a, p0b, p1b) -> tuple[Array, Array]:
    """Reference closest points of two segments: the distance oracle's (Ericson, RTCD §5.1.9)."""
    return segment_closest_points(*(np.asarray(p, dtype=float) for p in (p0a, p1a, p0b, p1b)))


def capsule_capsule_distance(p0a, p1a, ra: float, p0b, p1b, rb: float) -> float:
    """Reference signed distance of two capsules: segment distance minus the radii (exact for swept sets)."""
    ca, cb = closest_points_segment_segment(p0a, p1a, p0b, p1b)
    return float(np.linalg.norm(cb - ca)) - float(ra) - float(rb)


def _body(name: str, shape: Box | Capsule, T_body_shape: Array | None = None, shape_name: str = "s"
          ) -> CollisionBody:
    T = np.eye(4) if T_body_shape is None else T_body_shape
    return CollisionBody(name, (PlacedShape(shape_name, shape, T),))


def _two_body_scene(shape_a: Box | Capsule, shape_b: Box | Capsule, **kw) -> CollisionScene:
    return CollisionScene([_body("A", shape_a), _body("B", shape_b)], [("A", "B")], **kw)


def _dist(scene: CollisionScene, T_a: Array, T_b: Array) -> PairDistance:
    (pd,) = scene.distances({"A": T_a, "B": T_b})
    return pd


def _random_pose(rng: np.random.Generator, spread: float = 0.3) -> Array:
    return make_transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(size=3) * spread)


def _random_shape(rng: np.random.Generator, box: bool, min_length: float = 0.0) -> Box | Capsule:
    if box:
        return Box(tuple(rng.uniform(0.1, 0.8, 3)))
    return Capsule(rng.uniform(0.03, 0.2), rng.uniform(min_length, 0.8))


def _segment(T: Array, length: float) -> tuple[Array, Array]:
    """World end points of a capsule's segment (axis z of the shape frame, centred)."""
    return T[:3, 3] - 0.5 * length * T[:3, 2], T[:3, 3] + 0.5 * length * T[:3, 2]


def _capsule_reference(ca: Capsule, T_a: Array, cb: Capsule, T_b: Array) -> float:
    return capsule_capsule_distance(
        *_segment(T_a, ca.length_m), ca.radius_m, *_segment(T_b, cb.length_m), cb.radius_m
    )


def _half_extents(shape: Box | Capsule) -> tuple[Array, float]:
    """Core half extents along the shape axes (a capsule's core is a segment) and the sweep radius."""
    if isinstance(shape, Box):
        return 0.5 * np.asarray(shape.size_m, dtype=float), 0.0
    return np.array([0.0, 0.0, 0.5 * shape.length_m]), shape.radius_m


def _reference_distance(shape_a: Box | Capsule, T_a: Array, shape_b: Box | Capsule, T_b: Array) -> float:
    """Signed distance by least squares (separated cores) or SAT (penetrating cores), minus the radii."""
    ha, ra = _half_extents(shape_a)
    hb, rb = _half_extents(shape_b)
    Ra, Rb = T_a[:3, :3], T_b[:3, :3]
    A = np.hstack([Ra, -Rb])
    rhs = T_b[:3, 3] - T_a[:3, 3]
    h = np.r_[ha, hb]
    keep = h > 0.0
    sol = lsq_linear(A[:, keep], rhs, bounds=(-h[keep], h[keep]), method="bvls", tol=1e-15)
    core = float(np.linalg.norm(A[:, keep] @ sol.x - rhs))
    if core > 1e-12:
        return core - ra - rb
    edges_a = [Ra[:, k] for k in range(3) if ha[k] > 0]
    edges_b = [Rb[:, k] for k in range(3) if hb[k] > 0]
    faces = [Ra[:, k] for k in range(3) if np.all(ha > 0)] + [Rb[:, k] for k in range(3) if np.all(hb > 0)]
    axes = faces + [np.cross(ea, eb) for ea in edges_a for eb in edges_b]
    depth = np.inf
    for n in axes:
        nn = np.linalg.norm(n)
        if nn < 1e-9:
            continue
        n = n / nn
        overlap = np.abs(Ra.T @ n) @ ha + np.abs(Rb.T @ n) @ hb - abs(n @ rhs)
        depth = min(depth, overlap)
    return -depth - ra - rb


def _point_signed_distance(p: Array, shape: Box | Capsule, T: Array) -> float:
    """Signed distance (m) of a world point to a shape at pose T (negative inside)."""
    q = T[:3, :3].T @ (p - T[:3, 3])
    if isinstance(shape, Capsule):
        z = np.clip(q[2], -0.5 * shape.length_m, 0.5 * shape.length_m)
        return float(np.linalg.norm(q - np.array([0.0, 0.0, z]))) - shape.radius_m
    excess = np.abs(q) - 0.5 * np.asarray(shape.size_m)
    outside = float(np.linalg.norm(np.maximum(excess, 0.0)))
    return outside if outside > 0.0 else float(np.max(excess))


def _perturbed(T: Array, twist: Array) -> Array:
    """Pose moved for unit time by a world twist (linear velocity at the body origin, angular velocity)."""
    out = T.copy()
    angle = float(np.linalg.norm(twist[3:]))
    if angle > 0.0:  # Rodrigues rather than scipy's expm: no LAPACK call, no thread contention in CI
        out[:3, :3] = axis_angle_to_matrix(twist[3:], angle) @ T[:3, :3]
    out[:3, 3] = T[:3, 3] + twist[:3]
    return out


def _point_jacobian(p: Array, T: Array) -> Array:
    """3×6 Jacobian of a body-fixed point w.r.t. the body's world twist: ṗ = v + ω × (p - o)."""
    return np.hstack([I3, -skew(p - T[:3, 3])])


# ----------------------------------------------------------------------------------------- default_pairs
def test_default_pairs_chain_of_eight_plus_target_gives_29() -> None:
    chaser = ["base", "l1", "l2", "l3", "l4", "l5", "l6", "gripper"]
    adjacent = list(itertools.pairwise(chaser))
    pairs = default_pairs(chaser, adjacent, ["target"])
    assert len(pairs) == 29
    assert len({frozenset(p) for p in pairs}) == len(pairs), "duplicate (possibly reversed) pairs"
    adjacent_sets = {frozenset(p) for p in adjacent}
    assert not any(frozenset(p) in adjacent_sets for p in pairs)
    expected_chaser = {frozenset(c) for c in itertools.combinations(chaser, 2)} - adjacent_sets
    assert {frozenset(p) for p in pairs if "target" not in p} == expected_chaser
    assert [p for p in pairs if "target" in p] == [(c, "target") for c in chaser]  # target is always body B


def test_default_pairs_adjacency_is_unordered_and_names_checked() -> None:
    pairs = default_pairs(["a", "b", "c"], [("b", "a")], [])
    assert pairs == [("a", "c"), ("b", "c")]
    with pytest.raises(ValueError):
        default_pairs(["a", "b"], [("a", "x")], ["t"])


# ------------------------------------------------------------------------------- capsule_capsule_distance
@pytest.mark.parametrize(
    ("p0a", "p1a", "p0b", "p1b", "segment_distance"),
    [
        pytest.param([0, 0, 0], [0, 0, 1], [0.5, 0, 0.2], [0.5, 0, 1.2], 0.5, id="parallel-offset"),
        pytest.param([0, 0, 0], [0, 0, 1], [0.3, 0, 2], [0.3, 0, 3], np.hypot(0.3, 1), id="parallel-apart"),
        pytest.param([0, 0, -1], [0, 0, 1], [-1, 0.3, 0], [1, 0.3, 0], 0.3, id="perpendicular-offset"),
        pytest.param([0, 0, -1], [0, 0, 1], [-1, 0, 0.2], [1, 0, 0.2], 0.0, id="perpendicular-crossing"),
        pytest.param([0, 0, 0], [0, 0, 1], [1, 1, 2], [2, 2, 3], np.sqrt(3.0), id="cap-to-cap"),
        pytest.param([0, 0, 0], [0, 0, 1], [0, 0, 1.5], [0, 0, 2.5], 0.5, id="collinear-gap"),
        pytest.param([0, 0, 0], [0, 0, 1], [0, 0, 0.5], [0, 0, 2.5], 0.0, id="collinear-overlap"),
        pytest.param([0, 0, 0], [0, 0, 0], [3, 4, 0], [3, 4, 0], 5.0, id="two-points"),
        pytest.param([0, 0, 0], [0, 0, 2], [1, 0, 3], [1, 0, 3], np.sqrt(2.0), id="point-beyond-end"),
    ],
)
def test_capsule_capsule_distance_hand_cases(p0a, p1a, p0b, p1b, segment_distance) -> None:
    ra, rb = 0.07, 0.11
    d = capsule_capsule_distance(p0a, p1a, ra, p0b, p1b, rb)
    assert d == pytest.approx(segment_distance - ra - rb, abs=1e-12)
    # symmetric in the two capsules and in the direction of each segment
    assert capsule_capsule_distance(p1b, p0b, rb, p1a, p0a, ra) == pytest.approx(d, abs=1e-12)


def test_closest_points_segment_segment_are_on_segments_and_optimal() -> None:
    rng = np.random.default_rng(7)
    for _ in range(60):
        p0a, p1a, p0b, p1b = rng.normal(size=(4, 3))
        ca, cb = closest_points_segment_segment(p0a, p1a, p0b, p1b)
        # brute force over a fine grid of both parameters (never smaller than the analytic minimum)
        s = np.linspace(0.0, 1.0, 201)
        A = p0a + s[:, None] * (p1a - p0a)
        B = p0b + s[:, None] * (p1b - p0b)
        brute = np.min(np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2))
        assert np.linalg.norm(cb - ca) <= brute + 1e-12
        assert np.linalg.norm(cb - ca) >= brute - 1e-2  # grid step bound


# ------------------------------------------------------------------------- scene vs analytic: capsules
def _capsule_cases(rng: np.random.Generator) -> list[tuple[Capsule, Array, Capsule, Array, str]]:
    """Seeded capsule pairs: random (mixed), exactly crossing, parallel, and end-cap configurations."""
    cases = []
    for k in range(240):
        ca = Capsule(rng.uniform(0.03, 0.2), rng.uniform(0.0, 0.8))
        cb = Capsule(rng.uniform(0.03, 0.2), rng.uniform(0.0, 0.8))
        T_a = _random_pose(rng)
        kind = ("random", "crossing", "parallel", "endcap")[k % 4]
        if kind == "random":
            T_b = _random_pose(rng)
        elif kind == "crossing":  # B's segment passes through a point of A's segment
            p = T_a[:3, 3] + rng.uniform(-0.5, 0.5) * ca.length_m * T_a[:3, 2]
            R_b = Rotation.random(random_state=rng).as_matrix()
            T_b = make_transform(R_b, p - rng.uniform(-0.5, 0.5) * cb.length_m * R_b[:, 2])
        elif kind == "parallel":  # same axis direction, random offset (overlapping or not along the axis)
            T_b = make_transform(T_a[:3, :3], T_a[:3, 3] + rng.normal(size=3) * 0.3)
        else:  # B beyond A's end, tilted: the closest features are the caps or a cap and a side
            tip = T_a[:3, 3] + 0.5 * ca.length_m * T_a[:3, 2]
            R_b = Rotation.from_rotvec(rng.normal(size=3) * 0.5).as_matrix() @ T_a[:3, :3]
            offset = (ca.radius_m + cb.radius_m + 0.5 * cb.length_m) * rng.uniform(0.5, 1.5)
            T_b = make_transform(R_b, tip + offset * T_a[:3, 2] + rng.normal(size=3) * 0.05)
        cases.append((ca, T_a, cb, T_b, kind))
    return cases


def test_scene_capsule_capsule_matches_analytic_at_random_poses() -> None:
    rng = np.random.default_rng(2024)
    cases = _capsule_cases(rng)
    n_pen = 0
    for ca, T_a, cb, T_b, kind in cases:
        scene = _two_body_scene(ca, cb)
        pd = _dist(scene, T_a, T_b)
        ref = _capsule_reference(ca, T_a, cb, T_b)
        assert pd.distance_m == pytest.approx(ref, abs=1e-6), kind
        if kind == "crossing":
            assert ref == pytest.approx(-ca.radius_m - cb.radius_m, abs=1e-12)
        n_pen += ref < 0
    assert len(cases) >= 200
    assert 40 <= n_pen <= len(cases) - 40, "the sample must mix separated and penetrating pairs"


def test_scene_capsule_precision_is_machine_level() -> None:
    """The sphere-swept-core formulation is exact: measure the worst error, separated and penetrating."""
    rng = np.random.default_rng(5)
    errors = []
    for ca, T_a, cb, T_b, _ in _capsule_cases(rng):
        pd = _dist(_two_body_scene(ca, cb), T_a, T_b)
        ref = _capsule_reference(ca, T_a, cb, T_b)
        errors.append(abs(pd.distance_m - ref))
    assert max(errors) < 1e-12


# --------------------------------------------------------------------------- scene vs analytic: boxes
@pytest.mark.parametrize(
    ("T_b", "expected", "normal"),
    [
        pytest.param(make_transform(RX90, [0.8, 0.0, 0.0]), 0.2, [1, 0, 0], id="parallel-to-face-gap"),
        pytest.param(make_transform(RX90, [0.55, 0.1, 0.0]), -0.05, [1, 0, 0], id="parallel-to-face-inside"),
        # segment x ∈ [-0.3, 0.3] at y = 0.1 inside the box: the shortest exit is +y, 0.4 + radius 0.1
        pytest.param(make_transform(RY90, [0.0, 0.1, 0.0]), -0.5, [0, 1, 0], id="segment-inside-box"),
        pytest.param(make_transform(RY90, [0.88, 0.0, 0.0]), -0.02, [1, 0, 0], id="end-cap-into-face"),
        pytest.param(make_transform(RY90, [0.95, 0.0, 0.0]), 0.05, [1, 0, 0], id="end-cap-near-face"),
        pytest.param(make_transform(I3, [0.6, 0.6, 0.0]), np.sqrt(0.02) - 0.1, None, id="side-to-edge"),
    ],
)
def test_box_capsule_analytic_cases(T_b: Array, expected: float, normal: list[float] | None) -> None:
    box = Box((1.0, 1.0, 1.0))
    cap = Capsule(0.1, 0.6)
    pd = _dist(_two_body_scene(box, cap), np.eye(4), T_b)
    assert pd.distance_m == pytest.approx(expected, abs=BOX_TOL_M)
    if normal is not None:
        np.testing.assert_allclose(pd.normal_world, normal, atol=1e-12)
    np.testing.assert_allclose(pd.p_world_b - pd.p_world_a, pd.distance_m * pd.normal_world, atol=1e-12)


@pytest.mark.parametrize(
    ("T_b", "expected"),
    [
        pytest.param(make_transform(I3, [1.2, 0.1, 0.0]), 0.2, id="face-to-face-gap"),
        pytest.param(make_transform(I3, [0.9, 0.1, 0.05]), -0.1, id="face-to-face-penetrating"),
        pytest.param(make_transform(I3, [1.1, 1.1, 1.1]), np.sqrt(3.0) * 0.1, id="corner-to-corner"),
        # B turned 45° about z: its vertical edge sits √0.5 m ahead of its centre
        pytest.param(make_transform(RZ45, [0.5 + np.sqrt(0.5) + 0.1, 0, 0]), 0.1, id="edge-to-face-gap"),
        pytest.param(make_transform(RZ45, [0.5 + np.sqrt(0.5) - 0.05, 0, 0]), -0.05, id="edge-into-face"),
    ],
)
def test_box_box_analytic_cases(T_b: Array, expected: float) -> None:
    box = Box((1.0, 1.0, 1.0))
    pd = _dist(_two_body_scene(box, box), np.eye(4), T_b)
    assert pd.distance_m == pytest.approx(expected, abs=BOX_TOL_M)
    np.testing.assert_allclose(pd.p_world_b - pd.p_world_a, pd.distance_m * pd.normal_world, atol=1e-12)


@pytest.mark.parametrize("kind", ["box-capsule", "capsule-box", "box-box"])
def test_scene_boxes_match_least_squares_and_sat_references(kind: str) -> None:
    rng = np.random.default_rng({"box-capsule": 1, "capsule-box": 2, "box-box": 3}[kind])
    n_pen = 0
    for _ in range(80):
        box_a = Box(tuple(rng.uniform(0.1, 0.8, 3)))
        other = _random_shape(rng, box=kind == "box-box")
        sa, sb = (other, box_a) if kind == "capsule-box" else (box_a, other)
        T_a, T_b = _random_pose(rng), _random_pose(rng)
        pd = _dist(_two_body_scene(sa, sb), T_a, T_b)
        ref = _reference_distance(sa, T_a, sb, T_b)
        assert pd.distance_m == pytest.approx(ref, abs=1e-9)
        n_pen += ref < 0
    assert 15 <= n_pen <= 65


# -------------------------------------------------------------------------------------------- witnesses
@pytest.mark.parametrize("kind", ["capsule-capsule", "box-capsule", "box-box"])
def test_witness_points_on_surfaces_and_consistent_with_distance(kind: str) -> None:
    rng = np.random.default_rng(11)
    checked_sep = checked_pen = 0
    for _ in range(60):
        sa = _random_shape(rng, box=kind != "capsule-capsule")
        sb = _random_shape(rng, box=kind == "box-box")
        spread = 0.15 if kind == "capsule-capsule" else 0.3  # thin capsules need to be closer to penetrate
        T_a, T_b = _random_pose(rng, spread), _random_pose(rng, spread)
        pd = _dist(_two_body_scene(sa, sb), T_a, T_b)
        d = pd.distance_m
        assert np.linalg.norm(pd.normal_world) == pytest.approx(1.0, abs=1e-12)
        assert np.linalg.norm(pd.p_world_b - pd.p_world_a) == pytest.approx(abs(d), abs=1e-9)
        np.testing.assert_allclose(pd.p_world_b - pd.p_world_a, d * pd.normal_world, atol=1e-9)
        assert _point_signed_distance(pd.p_world_a, sa, T_a) == pytest.approx(0.0, abs=1e-9)
        assert _point_signed_distance(pd.p_world_b, sb, T_b) == pytest.approx(0.0, abs=1e-9)
        if d > 0:
            assert _point_signed_distance(pd.p_world_a, sb, T_b) == pytest.approx(d, abs=1e-9)
            assert _point_signed_distance(pd.p_world_b, sa, T_a) == pytest.approx(d, abs=1e-9)
            checked_sep += 1
        else:
            # minimum translation: moving B by the depth along n makes the bodies touch
            moved = T_b.copy()
            moved[:3, 3] += -d * pd.normal_world
            assert _dist(_two_body_scene(sa, sb), T_a, moved).distance_m == pytest.approx(0.0, abs=1e-9)
            checked_pen += 1
    assert checked_sep >= 5 and checked_pen >= 5


def test_degenerate_contacts_get_a_valid_normal() -> None:
    cap = Capsule(0.1, 1.0)
    # segments crossing exactly at both centres: depth r_a + r_b, normal ⟂ both axes
    scene = _two_body_scene(cap, cap)
    pd = _dist(scene, np.eye(4), make_transform(RY90, [0, 0, 0]))
    assert pd.distance_m == pytest.approx(-0.2, abs=1e-12)
    assert abs(pd.normal_world @ [0, 0, 1]) < 1e-9 and abs(pd.normal_world @ [1, 0, 0]) < 1e-9
    # the normal is a one-sided gradient: pushing B along it increases the distance by ε
    eps = 1e-4
    pushed = _dist(scene, np.eye(4), make_transform(RY90, eps * pd.normal_world))
    assert pushed.distance_m == pytest.approx(-0.2 + eps, abs=1e-9)
    # crossing off-centre and rotated: the centre difference lies in the plane of the two segments, so the
    # probe falls back to a world axis; the normal must still be ⟂ both segments and a valid push direction
    R_a = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    R_b = Rotation.from_rotvec([1.1, 0.4, -0.3]).as_matrix()
    crossing = np.array([0.1, 0.2, 0.3])
    T_a = make_transform(R_a, crossing - 0.3 * R_a[:, 2])
    T_b = make_transform(R_b, crossing + 0.2 * R_b[:, 2])
    pd = _dist(scene, T_a, T_b)
    assert pd.distance_m == pytest.approx(-0.2, abs=1e-12)
    assert abs(pd.normal_world @ R_a[:, 2]) < 1e-9 and abs(pd.normal_world @ R_b[:, 2]) < 1e-9
    pushed = _dist(scene, T_a, make_transform(R_b, T_b[:3, 3] + eps * pd.normal_world))
    assert pushed.distance_m == pytest.approx(-0.2 + eps, abs=1e-9)
    # boxes exactly touching face to face
    box = Box((1.0, 1.0, 1.0))
    pd = _dist(_two_body_scene(box, box), np.eye(4), make_transform(I3, [1.0, 0.2, 0.1]))
    assert pd.distance_m == pytest.approx(0.0, abs=BOX_TOL_M)
    # touching boxes: coal's normal comes from GJK's last simplex ~1e-10 m apart, a direction error ~1e-6
    np.testing.assert_allclose(pd.normal_world, [1, 0, 0], atol=1e-5)
    assert np.all(np.isfinite(pd.p_world_a)) and np.all(np.isfinite(pd.p_world_b))


# --------------------------------------------------------------------------------------------- gradient
@pytest.mark.parametrize("kind", ["capsule-capsule", "box-capsule", "box-box"])
def test_distance_gradient_matches_central_differences(kind: str) -> None:
    """x = (twist of A, twist of B), world frame. Tolerance 1e-4 relative for separated and penetrating pairs
    alike: the cores are polytopes, so fcl's GJK/EPA on them is exact to rounding (no EPA-precision slack is
    needed, unlike GJK/EPA on the curved capsules themselves, which is only ~1e-6 m accurate)."""
    rng = np.random.default_rng({"capsule-capsule": 21, "box-capsule": 22, "box-box": 23}[kind])
    h = 1e-6
    n_sep = n_pen = 0
    for _ in range(40):
        # capsules ≥ 0.1 m long: a sphere's distance is insensitive to B's rotation, a weak test of ω columns
        sa = _random_shape(rng, box=kind != "capsule-capsule", min_length=0.1)
        scene = _two_body_scene(sa, _random_shape(rng, box=kind == "box-box", min_length=0.1))
        T_a, T_b = _random_pose(rng), _random_pose(rng)
        pd = _dist(scene, T_a, T_b)
        J_a = np.hstack([_point_jacobian(pd.p_world_a, T_a), np.zeros((3, 6))])
        J_b = np.hstack([np.zeros((3, 6)), _point_jacobian(pd.p_world_b, T_b)])
        grad = distance_gradient(pd, J_a, J_b)
        fd = np.empty(12)
        for k in range(12):
            e = np.zeros(12)
            e[k] = h
            d_plus = _dist(scene, _perturbed(T_a, e[:6]), _perturbed(T_b, e[6:])).distance_m
            d_minus = _dist(scene, _perturbed(T_a, -e[:6]), _perturbed(T_b, -e[6:])).distance_m
            fd[k] = (d_plus - d_minus) / (2 * h)
        assert np.linalg.norm(grad - fd) <= 1e-4 * np.linalg.norm(fd), (pd.distance_m, grad, fd)
        n_sep += pd.distance_m > 0
        n_pen += pd.distance_m < 0
    assert n_sep >= 5 and n_pen >= 5


def test_distance_gradient_rejects_mismatched_jacobians() -> None:
    scene = _two_body_scene(Capsule(0.1, 0.5), Capsule(0.1, 0.5))
    pd = _dist(scene, np.eye(4), make_transform(I3, [1, 0, 0]))
    with pytest.raises(ValueError):
        distance_gradient(pd, np.zeros((3, 4)), np.zeros((3, 5)))


# ------------------------------------------------------------------------------------------- scaling
def test_overscaling_capsule_reduces_distance_by_twice_radius() -> None:
    cap_a, cap_b = Capsule(0.05, 0.4), Capsule(0.08, 0.4)
    # A's capsule is placed 0.2 m off A's origin: the placement must not be scaled
    bodies = [_body("A", cap_a, make_transform(I3, [0.2, 0, 0])), _body("B", cap_b)]
    T_b = make_transform(I3, [0.7, 0.0, 0.1])  # parallel side by side, the middle parts closest
    base = CollisionScene(bodies, [("A", "B")]).distances({"A": np.eye(4), "B": T_b})[0].distance_m
    assert base == pytest.approx(0.5 - 0.05 - 0.08, abs=1e-12)
    only_a = CollisionScene(bodies, [("A", "B")], scale={"A": 3.0}).distances({"A": np.eye(4), "B": T_b})[0]
    assert only_a.distance_m == pytest.approx(base - 2 * 0.05, abs=1e-12)
    both = CollisionScene(bodies, [("A", "B")], scale=3.0).distances({"A": np.eye(4), "B": T_b})[0]
    assert both.distance_m == pytest.approx(base - 2 * (0.05 + 0.08), abs=1e-12)


def test_overscaling_box_grows_half_sides() -> None:
    box_a, box_b = Box((0.2, 0.4, 0.6)), Box((0.2, 0.2, 0.2))
    bodies = [_body("A", box_a, make_transform(I3, [0.0, 0.0, 0.5])), _body("B", box_b)]
    poses = {"A": np.eye(4), "B": make_transform(I3, [1.0, 0.0, 0.5])}
    d1 = CollisionScene(bodies, [("A", "B")]).distances(poses)[0].distance_m
    d2 = CollisionScene(bodies, [("A", "B")], scale={"A": 2.0}).distances(poses)[0].distance_m
    assert d1 == pytest.approx(1.0 - 0.1 - 0.1, abs=BOX_TOL_M)
    assert d2 == pytest.approx(d1 - 0.1, abs=BOX_TOL_M)


def test_invalid_scale_rejected() -> None:
    bodies = [_body("A", Capsule(0.1, 0.5)), _body("B", Capsule(0.1, 0.5))]
    for bad in (0.0, -1.0, float("nan"), {"A": 0.0}, {"Z": 2.0}):
        with pytest.raises(ValueError):
            CollisionScene(bodies, [("A", "B")], scale=bad)


# ------------------------------------------------------------------------ multi-shape, bodies sharing a frame
def _grasp_scene(with_handle_body: bool = False) -> tuple[CollisionScene, dict[str, Array]]:
    hull = PlacedShape("hull", Box((1.0, 1.0, 1.0)))
    handle = PlacedShape("handle", Capsule(0.03, 0.3), make_transform(RY90, [0.75, 0.0, 0.0]))  # x ∈ [0.6, 0.9]
    gripper = _body("gripper", Capsule(0.05, 0.1), shape_name="fingers")
    link = _body("link3", Capsule(0.05, 0.1), shape_name="shell")
    poses = {"target": np.eye(4),
             # segment z ∈ [0.15, 0.25] at x = 0.8: 0.15 from the handle axis, 0.3 from the hull face x = 0.5
             "gripper": make_transform(I3, [0.8, 0.0, 0.2]),
             # segment z ∈ [-0.3, -0.2] at x = 0.7: 0.2 from the handle axis, 0.2 from the hull face x = 0.5
             "link3": make_transform(I3, [0.7, 0.0, -0.25])}
    if with_handle_body:
        bodies = [gripper, link, CollisionBody("target", (hull,)), CollisionBody("handle", (handle,), frame="target")]
        pairs = [("gripper", "target"), ("gripper", "handle"), ("link3", "target"), ("link3", "handle")]
        return CollisionScene(bodies, pairs), poses
    pairs = [("gripper", "target"), ("link3", "target")]
    return CollisionScene([gripper, link, CollisionBody("target", (hull, handle))], pairs), poses


def test_multi_shape_body_takes_minimum_over_shapes() -> None:
    scene, poses = _grasp_scene()
    grip, link = scene.distances(poses)
    assert grip.shape_pair == ("fingers", "handle")
    assert grip.distance_m == pytest.approx(0.15 - 0.05 - 0.03, abs=1e-12)
    assert link.shape_pair == ("shell", "handle")
    assert link.distance_m == pytest.approx(0.2 - 0.05 - 0.03, abs=1e-12)


def test_multi_shape_random_bodies_equal_minimum_of_single_shape_scenes() -> None:
    rng = np.random.default_rng(31)
    for _ in range(20):
        shapes = {
            body: tuple(
                PlacedShape(f"{body}{k}", _random_shape(rng, box=bool(rng.integers(2))), _random_pose(rng, 0.4))
                for k in range(3)
            )
            for body in ("A", "B")
        }
        poses = {"A": _random_pose(rng), "B": _random_pose(rng)}
        pd = CollisionScene([CollisionBody(b, s) for b, s in shapes.items()], [("A", "B")]).distances(poses)[0]
        singles = {
            (sa.name, sb.name): CollisionScene(
                [CollisionBody("A", (sa,)), CollisionBody("B", (sb,))], [("A", "B")]
            ).distances(poses)[0].distance_m
            for sa in shapes["A"]
            for sb in shapes["B"]
        }
        best = min(singles, key=singles.__getitem__)
        assert pd.distance_m == pytest.approx(singles[best], abs=1e-12)
        assert pd.shape_pair == best


def test_handle_body_moves_with_the_target_frame_and_pairs_apart() -> None:
    """A body with ``frame="target"`` takes the target's pose; its pairs are reported apart from the hull's."""
    scene, poses = _grasp_scene(with_handle_body=True)
    grip_hull, grip_handle, link_hull, link_handle = scene.distances(poses)
    assert grip_hull.shape_pair == ("fingers", "hull") and grip_hull.distance_m == pytest.approx(0.3 - 0.05, abs=1e-12)
    assert grip_handle.distance_m == pytest.approx(0.15 - 0.05 - 0.03, abs=1e-12)
    assert link_hull.distance_m == pytest.approx(0.2 - 0.05, abs=1e-12)
    assert link_handle.distance_m == pytest.approx(0.2 - 0.05 - 0.03, abs=1e-12)
    moved = dict(poses, target=make_transform(I3, [0.0, 0.0, 0.1]))  # the handle moves with it
    assert scene.distances(moved)[1].distance_m == pytest.approx(0.05 - 0.05 - 0.03, abs=1e-12)
    assert scene.frame_of("handle") == "target" and scene.frame_of("gripper") == "gripper"


def test_scene_validation() -> None:
    bodies = [_body("A", Capsule(0.1, 0.5)), _body("B", Capsule(0.1, 0.5))]
    for pairs in ([("A", "Z")], [("A", "A")], [("A", "B"), ("B", "A")]):
        with pytest.raises(ValueError):
            CollisionScene(bodies, pairs)
    with pytest.raises(ValueError):  # a body without shapes
        CollisionScene([*bodies, CollisionBody("C", ())], [("A", "B")])
    scene = CollisionScene(bodies, [("A", "B")])
    assert scene.pairs == (("A", "B"),)
    with pytest.raises(KeyError):
        scene.distances({"A": np.eye(4)})


def test_distance_arrays_are_the_distances_as_rows() -> None:
    """The callbacks' array form reports exactly what the per-pair objects do, pair by pair."""
    scene, poses = _grasp_scene(with_handle_body=True)
    rng = np.random.default_rng(5)
    for _ in range(5):
        moved = {name: T @ _random_pose(rng, 0.05) for name, T in poses.items()}
        d, p_a, p_b, n = scene.distance_arrays(moved)
        objects = scene.distances(moved)
        assert d.shape == (len(scene.pairs),)
        for k, pd in enumerate(objects):
            assert d[k] == pd.distance_m
            np.testing.assert_array_equal(p_a[k], pd.p_world_a)
            np.testing.assert_array_equal(p_b[k], pd.p_world_b)
            np.testing.assert_array_equal(n[k], pd.normal_world)
