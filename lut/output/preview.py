"""A 3D preview of one plan: ONE self-contained HTML file that plays the maneuver in a browser, offline.

Why plotly: its WebGL 3D scene (``mesh3d``/``scatter3d``) gives orbit/zoom/pan, hover and a legend for
free; it is a well-kept library (MIT, plotly.py + plotly.js), on PyPI, and ships the whole plotly.js
bundle inside the wheel, so the page embeds it (what ``include_plotlyjs=True`` does) and loads no
network resource. The alternatives were worse here: three.js would need our own camera controls and a
bundle we vendor ourselves; matplotlib animations are raster video without interaction; pythreejs and
k3d need a Jupyter kernel.

What the page shows, in the orbital frame O (m): the chaser base box and arm capsules (the URDF's
collision shapes, posed by pinocchio from the exported base pose and joint angles), the target's shapes
(the handle in orange), the grasp frame (x red, y green, z blue), the gripper's and the grasp point's
paths, and per frame the time, phase and smallest collision distance with its pair (``samples.min_distance_m``,
``samples.closest_pair``; the witness segment when ``samples.closest_points_m`` is there).
Controls: play/pause, a time slider, a speed choice. ``preview.html?t=20`` (or ``#t=20``) opens at the
frame nearest to t = 20 s since the observation; ``&play=1`` starts playing.

Size: meshes are sent once; each frame carries one 3×4 pose per body (≤ :data:`MAX_FRAMES` frames),
so the page is the plotly.js bundle (~5 MB) plus a few hundred kB.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray
from plotly.offline import get_plotlyjs

from lut.output.plan_file import PlanFileError, check_plan, phase_spans, plan_label, resolve_robot_urdf, sample_arrays
from lut.output.preview_geometry import Mesh, chaser_body_poses, merge, placed_mesh, pose_matrices, target_shapes
from lut.output.preview_page import page_html
from planner.model.robot import RobotModel

Array = NDArray[np.float64]
MAX_FRAMES = 300
DECIMALS = 4  # 0.1 mm and 1e-4 rotation-matrix entries: invisible on screen, halves the page size
AXIS_LENGTH_M = 0.35  # grasp-frame triad
COLORS = {"base": "#c9a33a", "arm": "#4a78b5", "target": "#a7b0ba", "handle": "#f08a24"}


def frame_indices(t: Array, max_frames: int = MAX_FRAMES) -> NDArray[np.int64]:
    """At most ``max_frames`` sample indices at an even stride, always with the first and last sample."""
    n = len(t)
    if n <= max_frames:
        return np.arange(n)
    stride = int(np.ceil((n - 1) / (max_frames - 1)))
    idx = np.arange(0, n, stride)
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


def _mesh_trace(mesh: Mesh, name: str, color: str, opacity: float) -> go.Mesh3d:
    """A mesh3d trace with the faces fixed; its vertices are written by the page for each frame."""
    v, f = mesh.vertices, mesh.faces
    return go.Mesh3d(x=v[:, 0], y=v[:, 1], z=v[:, 2], i=f[:, 0], j=f[:, 1], k=f[:, 2], name=name, color=color,
                     opacity=opacity, flatshading=True, showlegend=True, hoverinfo="name",
                     lighting={"ambient": 0.55, "diffuse": 0.8, "specular": 0.15})


def _phase_of(t: Array, phases: dict[str, tuple[float, float]]) -> list[str]:
    names = []
    for tk in t:
        name = "before approach"
        for phase, (t0, _) in phases.items():
            if tk >= t0 - 1e-9:
                name = phase
        names.append(name)
    return names


def _round(a: Array) -> list:
    return np.round(np.asarray(a, dtype=float), DECIMALS).tolist()


def _load_robot(doc: dict[str, Any]) -> RobotModel:
    """The chaser the plan names (its URDF gives the arm's shapes); :class:`PlanFileError` if it is not there."""
    from planner.errors import LutgenError
    from planner.model.urdf import load_robot

    urdf = resolve_robot_urdf(doc)
    if urdf is None:
        raise PlanFileError(f"robot_urdf: {doc.get('robot_urdf')!r} not found (from the current directory or the "
                            "lutgen source tree); the preview needs the robot's shapes: run from the directory the "
                            "plan was made in")
    try:
        return load_robot(urdf, ee_frame=doc.get("ee_frame", "grasp_frame"))
    except LutgenError as exc:
        raise PlanFileError(f"robot_urdf: {exc}") from None


def _add_meshes(fig: go.Figure, robot: RobotModel, doc: dict[str, Any]) -> tuple[list[dict[str, Any]], str]:
    """Mesh traces of the base, the arm, the target and its handle; per trace its local vertices and the body
    (index into the page's poses: chaser bodies, then the target) that moves each vertex; the target note."""
    target_body = len(robot.body_names)
    shapes, note = target_shapes(doc)
    groups: list[tuple[str, str, float, list[tuple[int, Mesh]]]] = [
        ("chaser base", COLORS["base"], 1.0, [(0, placed_mesh(p)) for p in robot.collision_shapes[0]]),
        ("arm", COLORS["arm"], 1.0, [(b, placed_mesh(p)) for b in range(1, target_body)
                                     for p in robot.collision_shapes[b]]),
        # a stand-in target box is far larger than the real target: see-through, so the arm stays visible
        ("target (stand-in box)" if note else "target", COLORS["target"], 0.35 if note else 1.0,
         [(target_body, placed_mesh(p)) for p, handle in shapes if not handle]),
        ("target handle", COLORS["handle"], 1.0, [(target_body, placed_mesh(p)) for p, handle in shapes if handle]),
    ]
    meshes = []
    for name, color, opacity, parts in groups:
        if not parts:
            continue
        mesh = merge([m for _, m in parts])
        body_of_vertex = np.concatenate([np.full(len(m.vertices), b) for b, m in parts])
        meshes.append({"trace": len(fig.data), "local": _round(mesh.vertices.ravel()), "body": body_of_vertex.tolist()})
        fig.add_trace(_mesh_trace(mesh, name, color, opacity))
    return meshes, note


def _add_markers(fig: go.Figure, s: dict[str, Array]) -> dict[str, int]:
    """Static paths of the gripper and the grasp point; the traces the page moves: joint chain, grasp-frame
    triad and (when the plan has witness points) the closest-pair segment. Returns the moving traces' indices."""
    for key, name, color in (("ee_position", "gripper path", COLORS["arm"]),
                             ("grasp_position", "grasp point path", COLORS["handle"])):
        p = s[key]
        fig.add_trace(go.Scatter3d(x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="lines", name=name,
                                   line={"color": color, "width": 2, "dash": "dot"}, opacity=0.6, hoverinfo="name"))
    dynamic = {"skeleton": len(fig.data)}
    fig.add_trace(go.Scatter3d(x=[0], y=[0], z=[0], mode="lines+markers", name="joints",
                               line={"color": "#1d2b3a", "width": 4}, marker={"size": 3, "color": "#1d2b3a"},
                               hoverinfo="name"))
    dynamic["triad"] = len(fig.data)
    for axis, color in zip("xyz", ("#d62728", "#2ca02c", "#1f5fd6"), strict=True):
        fig.add_trace(go.Scatter3d(x=[0, 0], y=[0, 0], z=[0, 0], mode="lines", hoverinfo="name",
                                   name="grasp frame (x r, y g, z b)" if axis == "z" else f"grasp frame {axis}",
                                   line={"color": color, "width": 6}, showlegend=axis == "z",
                                   legendgroup="grasp frame"))
    if "closest_points_m" in s:
        dynamic["closest"] = len(fig.data)
        fig.add_trace(go.Scatter3d(x=[0, 0], y=[0, 0], z=[0, 0], mode="lines+markers", name="closest pair",
                                   line={"color": "#e3242b", "width": 5}, marker={"size": 3, "color": "#e3242b"},
                                   hoverinfo="name"))
    return dynamic


def _fixed_view(fig: go.Figure, poses: Array, meshes: list[dict[str, Any]], paths: list[Array]) -> None:
    """Axes (one scale, m) around everything that ever appears, so the view does not jump while playing."""
    n_frames = len(poses)
    world = []
    for m in meshes:
        local = np.asarray(m["local"]).reshape(-1, 3)
        P = poses[:, np.asarray(m["body"])]  # frames × vertices × 3 × 4
        world.append((np.einsum("fvij,vj->fvi", P[..., :3], local) + P[..., 3]).reshape(-1, 3))
    pts = np.vstack(world + paths) if n_frames else np.zeros((1, 3))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max((hi - lo).max() / 2 * 1.05, 0.5)
    axes = {f"{c}axis": {"range": [centre[i] - half, centre[i] + half], "title": f"{c} [m]"}
            for i, c in enumerate("xyz")}
    fig.update_layout(
        scene={**axes, "aspectmode": "cube", "camera": {"eye": {"x": 0.75, "y": -1.45, "z": 0.65}}},
        margin={"l": 0, "r": 0, "t": 0, "b": 0}, legend={"x": 0.0, "y": 1.0, "bgcolor": "rgba(255,255,255,0.7)"},
        uirevision="keep",  # restyling a frame must not reset the camera the user chose
    )


def preview_data(doc: dict[str, Any], max_frames: int = MAX_FRAMES) -> tuple[go.Figure, dict[str, Any], str]:
    """The plotly figure (static parts), the per-frame data the page plays, and a note ("" or why the target
    is a stand-in).

    Raises :class:`PlanFileError` on a malformed document or when the robot URDF the plan names cannot be
    found (the arm's shapes come from it).
    """
    check_plan(doc)
    robot = _load_robot(doc)
    s = sample_arrays(doc)
    if s["q"].shape[1] != robot.n_joints:
        raise PlanFileError(f"samples.q: {s['q'].shape[1]} joints, the robot {robot.urdf_path} has {robot.n_joints}")
    idx = frame_indices(s["t"], max_frames)
    chaser = chaser_body_poses(robot, s["base_position"][idx], s["base_wxyz"][idx], s["q"][idx])
    target = pose_matrices(s["target_position"][idx], s["target_wxyz"][idx])
    poses = np.concatenate([chaser, target[:, None]], axis=1)  # frames × (chaser bodies + target) × 3 × 4

    fig = go.Figure()
    meshes, note = _add_meshes(fig, robot, doc)
    dynamic = _add_markers(fig, s)
    _fixed_view(fig, poses, meshes, [s["ee_position"], s["grasp_position"]])

    t = s["t"][idx]
    pairs = doc["samples"].get("closest_pair")
    frames = {
        "t": _round(t), "phase": _phase_of(t, phase_spans(doc)),
        "poses": _round(poses.reshape(len(idx), -1)),
        "grasp": _round(pose_matrices(s["grasp_position"][idx], s["grasp_wxyz"][idx]).reshape(len(idx), -1)),
        "ee": _round(s["ee_position"][idx]),
        "min_distance_m": _round(s["min_distance_m"][idx]) if "min_distance_m" in s else None,
        "closest_pair": [pairs[k] for k in idx] if pairs is not None else None,
        "closest_points": _round(s["closest_points_m"][idx].reshape(len(idx), -1)) if "closest_points_m" in s
        else None,
    }
    data = {"title": f"{plan_label(doc)} — {Path(str(doc.get('robot_urdf', ''))).name}",
            "meshes": meshes, "dynamic": dynamic, "frames": frames, "n_bodies": int(poses.shape[1]),
            "skeleton_bodies": list(range(len(robot.body_names))), "axis_length_m": AXIS_LENGTH_M,
            "margin_m": doc.get("metrics", {}).get("limits", {}).get("collision_margin_m"), "note": note}
    return fig, data, note


def write_preview(doc: dict[str, Any], out_html: str | Path, max_frames: int = MAX_FRAMES) -> Path:
    """Write the self-contained preview page of plan document ``doc`` to ``out_html``; return its path.

    The parent folder is created if missing. Raises :class:`PlanFileError` on a malformed document or
    when the robot URDF cannot be found.
    """
    fig, data, _ = preview_data(doc, max_frames)
    html = page_html(get_plotlyjs(), fig.to_json(), json.dumps(data, separators=(",", ":")), data["title"])
    out = Path(out_html)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(html, encoding="utf-8")
    tmp.replace(out)
    return out
