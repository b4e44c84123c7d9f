"""The handle-contact rule: the clearance [m] every collision pair must keep, phase by phase.

* Approach: every pair keeps ``limits.collision_margin_m``, the gripper against the handle included.
* Tracking: the gripper–handle pair keeps the margin *less the distance the back-off has closed*,
  ``margin − (b₀ − b(t))`` with ``b(t)`` the remaining back-off (:func:`~planner.phases.tracking_profile.
  backoff_m`): the gripper may move onto the handle along its approach axis, and only by as much as the
  planned closing; a sideways sweep into the handle still violates it. At the grasp the bound is
  ``margin − b₀``; the pre-grasp back-off is chosen so that the grasp pose itself keeps it (docs/phases.md, Collision).
* Stabilization: the gripper–handle pair is exempt (the gripper holds the handle).
Every other pair keeps the margin at all times. The NLPs add their constraint back-off on top of this
rule; :func:`planner.verify.verifier.verify` checks the rule itself.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from planner.phases.tracking_profile import backoff_m

APPROACH, TRACKING, STABILIZATION = 0, 1, 2  # phase indices, as in a plan's phase_index


def closed_backoff_m(backoff0_m: float, t_into_tracking_s: float, tracking_s: float) -> float:
    """How much of the pre-grasp back-off ``backoff0_m`` [m] the tracking has closed ``t`` s into it."""
    return backoff0_m - backoff_m(backoff0_m, t_into_tracking_s, tracking_s)


def required_clearance_m(pairs: Sequence[tuple[str, str]], gripper_handle: tuple[str, str] | None, margin_m: float,
                         phase: int, closed_m: float = 0.0) -> NDArray[np.float64]:
    """Per pair, the smallest signed distance allowed (m; ``-inf``: exempt) in ``phase``.

    ``closed_m`` is :func:`closed_backoff_m` at that instant (tracking only).
    """
    out = np.full(len(pairs), float(margin_m))
    if gripper_handle is None or gripper_handle not in pairs:
        return out
    k = list(pairs).index(gripper_handle)
    if phase == TRACKING:
        out[k] = margin_m - closed_m
    elif phase == STABILIZATION:
        out[k] = -np.inf
    return out


def exemption_note(gripper_handle: tuple[str, str] | None) -> str:
    """One line for a plan's metrics: which pair was exempt or relaxed, when."""
    if gripper_handle is None:
        return "no handle: every pair keeps the margin in every phase"
    pair = f"{gripper_handle[0]}-{gripper_handle[1]}"
    return (f"{pair}: the margin in the approach, the margin less the closed back-off in tracking, exempt from the "
            f"grasp on; every other pair keeps the margin in every phase")
