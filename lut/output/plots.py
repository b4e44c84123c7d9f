"""Figures of one plan, read from its ``lutgen.plan/1`` JSON document (docs/table.md, Plan file), as PNG files.

One figure per question a person asks before a plan runs; every time axis is in s since the
observation and shows the phase boundaries (``doc["phases"]``) as dotted lines:

* ``attitude.png`` — chaser base roll/pitch/yaw (deg) over the whole maneuver (paper Fig. 2). Angles are
  ``R_world_base = Rz(yaw) Ry(pitch) Rx(roll)`` (the URDF convention), in the orbital frame O.
* ``grasp_wrench.png`` — force (N) and torque (N·m) the gripper exerts on the target during the
  stabilization, grasp-frame components, with the limits of ``metrics.limits`` (paper Fig. 3).
* ``joints.png`` — every joint's position (deg) and velocity (deg/s) against the URDF limits.
* ``collision_distance.png`` — smallest signed distance over the collision pairs held to the full margin (m; the
  gripper–handle pair is not, from the start of tracking: README "Collision model") and the margin
  (``metrics.limits.collision_margin_m``), with the pair that realises it. Needs ``samples.min_distance_m``
  (and ``samples.closest_pair`` for the pair); a plan without them gets a figure that says so.
* ``tracking.png`` — gripper vs grasp frame during tracking: distance (mm), relative velocity (mm/s, by
  central finite differences of the sampled positions) and relative rotation (deg); all → 0 at the grasp.

Each PNG carries its title in the ``Title`` metadata (tests and tools read it back).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from lut.output.plan_file import check_plan, phase_spans, plan_label, resolve_robot_urdf, sample_arrays
from lut.output.plot_style import LIMIT_STYLE, mark_phases, new_figure, save_figure
from planner.errors import LutgenError

Array = NDArray[np.float64]

TITLES = {
    "attitude": "Chaser base attitude",
    "grasp_wrench": "Grasp wrench during stabilization",
    "joints": "Joint positions and velocities vs limits",
    "collision_distance": "Minimum collision distance",
    "tracking": "Gripper vs grasp frame during tracking",
}
COMPONENT_COLORS = ("tab:blue", "tab:orange", "tab:green")
# share of the stabilization shown before the grasp in the wrench figure: the jump from zero is visible
PRE_GRASP_SHARE = 0.04


def _title(key: str, doc: dict[str, Any], note: str = "") -> str:
    return f"{TITLES[key]} — {plan_label(doc)}" + (f" ({note})" if note else "")


def _rotations(wxyz: Array) -> Rotation:
    """scipy rotations from ``[w, x, y, z]`` quaternions (scipy stores ``[x, y, z, w]``)."""
    return Rotation.from_quat(np.asarray(wxyz)[:, [1, 2, 3, 0]])


def _window(t: Array, t0: float, t1: float) -> NDArray[np.bool_]:
    """Samples with t0 ≤ t ≤ t1 (s), with a little slack for rounding of the stored times."""
    eps = 1e-6
    return (t >= t0 - eps) & (t <= t1 + eps)


# ---- figures --------------------------------------------------------------------------------------


def attitude_figure(doc: dict[str, Any]) -> tuple[Figure, str]:
    """Base roll, pitch, yaw (deg) vs time over the whole maneuver (paper Fig. 2)."""
    s = sample_arrays(doc)
    t = s["t"]
    # intrinsic Z-Y-X = Rz(yaw) Ry(pitch) Rx(roll); unwrap so a full turn does not jump by 360°
    ypr = np.degrees(np.unwrap(_rotations(s["base_wxyz"]).as_euler("ZYX"), axis=0))
    fig = new_figure(9, 4.5)
    ax = fig.add_subplot()
    for (name, column), color in zip((("roll", 2), ("pitch", 1), ("yaw", 0)), COMPONENT_COLORS, strict=True):
        ax.plot(t, ypr[:, column], color=color, label=name)
    ax.set_xlabel("time since observation [s]")
    ax.set_ylabel("base attitude in orbital frame [deg]")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    mark_phases(ax, phase_spans(doc))
    return fig, _title("attitude", doc)


def _limit_lines(ax: Axes, limit: float | None, unit: str) -> str:
    """±limit lines; the legend text for them (or that there is no limit)."""
    if limit is None:
        return "no limit (unconstrained)"
    ax.axhline(limit, **LIMIT_STYLE, label=f"limit ±{limit:g} {unit}")
    ax.axhline(-limit, **LIMIT_STYLE)
    return ""


def grasp_wrench_figure(doc: dict[str, Any]) -> tuple[Figure, str]:
    """Grasp force (N) and torque (N·m), grasp-frame components, during the stabilization (paper Fig. 3)."""
    s = sample_arrays(doc)
    phases = phase_spans(doc)
    t0, t1 = phases["stabilization"]
    sel = _window(s["t"], t0 - PRE_GRASP_SHARE * (t1 - t0), t1)
    t, wrench = s["t"][sel], s["grasp_wrench"][sel]
    limits = doc.get("metrics", {}).get("limits", {})
    fig = new_figure(9, 6.5)
    axes = fig.subplots(2, 1, sharex=True)
    panels = ((axes[0], wrench[:, :3], "F", "force on target [N]", "N", limits.get("grasp_force_max_n")),
              (axes[1], wrench[:, 3:], "M", "torque on target [N·m]", "N·m", limits.get("grasp_torque_max_nm")))
    for ax, values, symbol, ylabel, unit, limit in panels:
        for k, (axis, color) in enumerate(zip("xyz", COMPONENT_COLORS, strict=True)):
            ax.plot(t, values[:, k], color=color, label=f"{symbol}{axis}")
        note = _limit_lines(ax, limit, unit)
        peak = float(np.abs(values).max()) if len(values) else 0.0
        if limit is not None:  # the limit lines inside the frame, not on it
            span = 1.15 * max(limit, peak)
            ax.set_ylim(-span, span)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", ncols=4, fontsize=8,
                  title=f"peak |{symbol}| {peak:.3g} {unit}" + (f"; {note}" if note else ""), title_fontsize=8)
        mark_phases(ax, phases, label=ax is axes[0])
    axes[1].set_xlabel("time since observation [s]  (components in the grasp frame; 0 before the grasp)")
    return fig, _title("grasp_wrench", doc)


def _joint_limits(doc: dict[str, Any]) -> tuple[tuple[Array, Array, Array] | None, str]:
    """(q_min, q_max, qd_max) in rad and rad/s from the plan's robot URDF, or None and why not."""
    path = resolve_robot_urdf(doc)
    if path is None:
        return None, f"robot URDF {doc.get('robot_urdf')!r} not found: no limit lines"
    from planner.model.urdf import load_robot  # pinocchio: only when a URDF is there to read

    try:
        robot = load_robot(path, ee_frame=doc.get("ee_frame", "grasp_frame"))
    except LutgenError as exc:
        return None, f"robot URDF unreadable ({exc}): no limit lines"
    return (robot.q_min, robot.q_max, robot.qd_max), ""


def joints_figure(doc: dict[str, Any]) -> tuple[Figure, str]:
    """Every joint's position (deg) and velocity (deg/s) vs time, with the URDF limits as dashed lines."""
    s = sample_arrays(doc)
    t, q, qd = s["t"], np.degrees(s["q"]), np.degrees(s["qd"])
    limits, note = _joint_limits(doc)
    n = q.shape[1]
    if limits is not None and len(limits[0]) != n:
        limits, note = None, f"URDF has {len(limits[0])} joints, plan {n}: no limit lines"
    phases = phase_spans(doc)
    fig = new_figure(12, 1.6 * n + 1.4)
    columns = fig.subfigures(1, 2)
    columns[0].suptitle("joint position", fontsize=10)
    columns[1].suptitle("joint velocity", fontsize=10)
    axes_q = columns[0].subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    axes_v = columns[1].subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    for j in range(n):
        ax_q, ax_v = axes_q[j], axes_v[j]
        ax_q.plot(t, q[:, j], color="tab:blue")
        ax_v.plot(t, qd[:, j], color="tab:purple")
        if limits is not None:
            _joint_limit_lines(ax_q, ax_v, q[:, j], qd[:, j], *(np.degrees(v[j]) for v in limits))
        ax_q.set_ylabel(f"q{j + 1} [deg]")
        ax_v.set_ylabel(f"q̇{j + 1} [deg/s]")
        for ax in (ax_q, ax_v):
            ax.grid(alpha=0.3)
            mark_phases(ax, phases, label=j == 0)
    for ax in (axes_q[-1], axes_v[-1]):
        ax.set_xlabel("time since observation [s]")
    if limits is not None:
        axes_v[-1].plot([], [], **LIMIT_STYLE, label="URDF limit")
        axes_v[-1].legend(loc="lower left", fontsize=7)
    return fig, _title("joints", doc, note)


def _joint_limit_lines(ax_q: Axes, ax_v: Axes, q: Array, qd: Array, q_min: float, q_max: float,
                       qd_max: float) -> None:
    """One joint's URDF limits as dashed lines and its margins written in (angles [deg], rates [deg/s])."""
    ax_q.axhline(q_min, **LIMIT_STYLE)
    ax_q.axhline(q_max, **LIMIT_STYLE)
    ax_v.axhline(qd_max, **LIMIT_STYLE)
    ax_v.axhline(-qd_max, **LIMIT_STYLE)
    margin_q = min(q.min() - q_min, q_max - q.max())
    margin_v = qd_max - np.abs(qd).max()
    # red where the motion uses more than 95 % of the room the limits give
    for ax, text, tight in ((ax_q, f"margin {margin_q:.3g}°", margin_q < 0.05 * (q_max - q_min)),
                            (ax_v, f"margin {margin_v:.3g}°/s", margin_v < 0.05 * 2 * qd_max)):
        ax.text(0.995, 0.93, text, transform=ax.transAxes, ha="right", va="top", fontsize=7,
                color="tab:red" if tight else "black",
                bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1})


def collision_distance_figure(doc: dict[str, Any]) -> tuple[Figure, str]:
    """Smallest signed distance over all collision pairs (m) vs time, the margin, the closest pair."""
    s = sample_arrays(doc)
    phases = phase_spans(doc)
    margin = doc.get("metrics", {}).get("limits", {}).get("collision_margin_m")
    if "min_distance_m" not in s:
        fig = new_figure(9, 3)
        ax = fig.add_subplot()
        ax.set_axis_off()
        ax.text(0.5, 0.5, "This plan file has no per-sample distances (samples.min_distance_m):\n"
                "it was exported by a lutgen that did not write them. Re-export the plan to see this figure.\n"
                f"Worst distance over the plan (metrics.costs.min_distance_m): "
                f"{doc.get('metrics', {}).get('costs', {}).get('min_distance_m', 'n/a')} m",
                ha="center", va="center", fontsize=10, transform=ax.transAxes)
        return fig, _title("collision_distance", doc, "not in plan file")
    t, d = s["t"], s["min_distance_m"]
    pairs = doc["samples"].get("closest_pair")
    fig = new_figure(9, 6 if pairs else 4.5)
    if pairs:
        ax, ax_pair = fig.subplots(2, 1, sharex=True, height_ratios=(2.2, 1))
    else:
        ax, ax_pair = fig.add_subplot(), None
    ax.plot(t, d, color="tab:blue", label="min signed distance, pairs held to the margin")
    if margin is not None:
        ax.axhline(margin, **LIMIT_STYLE, label=f"margin {margin:g} m")
    k = int(np.argmin(d))
    where = f" ({pairs[k]})" if pairs else ""
    ax.plot(t[k], d[k], "o", color="tab:red", label=f"min {d[k]:.4g} m at t = {t[k]:.2f} s{where}")
    ax.set_ylim(bottom=min(0.0, float(d.min()) * 1.1))
    ax.set_ylabel("distance [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8, framealpha=0.9)
    mark_phases(ax, phases)
    if ax_pair is not None:
        bodies = [p.split(" ")[0] for p in pairs]  # "A-B (shape_a/shape_b)": one row per body pair
        names = sorted(set(bodies), key=bodies.index)
        ax_pair.scatter(t, [names.index(b) for b in bodies], s=4, color="tab:blue")
        ax_pair.set_yticks(range(len(names)), names, fontsize=7)
        ax_pair.set_ylabel("closest pair")
        ax_pair.grid(alpha=0.3)
        mark_phases(ax_pair, phases, label=False)
    (ax_pair or ax).set_xlabel("time since observation [s]")
    return fig, _title("collision_distance", doc)


def tracking_figure(doc: dict[str, Any]) -> tuple[Figure, str]:
    """Gripper-to-grasp distance (mm), relative velocity (mm/s) and relative rotation (deg) during tracking."""
    s = sample_arrays(doc)
    phases = phase_spans(doc)
    sel = _window(s["t"], *phases["tracking"])
    t = s["t"][sel]
    delta = s["ee_position"][sel] - s["grasp_position"][sel]
    # d/dt (p_ee − p_grasp) = v_ee − v_grasp: the grasp frame's origin is a material point of the target
    rel_velocity = np.gradient(delta, t, axis=0) if len(t) > 1 else np.zeros_like(delta)
    rel_rotation = (_rotations(s["grasp_wxyz"][sel]).inv() * _rotations(s["ee_wxyz"][sel])).magnitude()
    fig = new_figure(9, 7)
    axes = fig.subplots(3, 1, sharex=True)
    series = ((1e3 * np.linalg.norm(delta, axis=1), "distance", "mm", "tab:blue"),
              (1e3 * np.linalg.norm(rel_velocity, axis=1), "relative velocity", "mm/s", "tab:orange"),
              (np.degrees(rel_rotation), "relative rotation", "deg", "tab:green"))
    for ax, (values, name, unit, color) in zip(axes, series, strict=True):
        ax.plot(t, values, color=color)
        ylabel = f"{name} [{unit}]"
        if len(values):
            ax.annotate(f"{values[-1]:.3g} {unit} at the grasp", (t[-1], values[-1]), xytext=(-10, 12),
                        textcoords="offset points", ha="right", fontsize=8)
        ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        mark_phases(ax, phases, label=ax is axes[0])
    axes[-1].set_xlabel("time since observation [s]  (velocity: finite differences of the sampled positions)")
    return fig, _title("tracking", doc)


FIGURES: dict[str, Callable[[dict[str, Any]], tuple[Figure, str]]] = {
    "attitude": attitude_figure,
    "grasp_wrench": grasp_wrench_figure,
    "joints": joints_figure,
    "collision_distance": collision_distance_figure,
    "tracking": tracking_figure,
}


def write_plots(doc: dict[str, Any], out_dir: str | Path) -> list[Path]:
    """Write every figure of the plan document ``doc`` as ``<out_dir>/<name>.png``; return the paths.

    ``out_dir`` is created if missing. Raises :class:`lut.output.plan_file.PlanFileError` on a malformed document.
    """
    check_plan(doc)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, make in FIGURES.items():
        fig, title = make(doc)
        written.append(save_figure(fig, out / f"{name}.png", title))
    return written
