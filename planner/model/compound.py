"""The compound chaser + target after the grasp, and its grasp geometry as NLP parameters (paper §4.1.1).

At the grasp the target becomes rigidly attached to the gripper, and "the inertial parameters of the last
robot link are updated accordingly" (:meth:`planner.model.robot.RobotModel.with_payload`). Where the target was
grasped, ``T_ee_target``, sets that inertia and the lever arms of the grasp wrench; with a free grasp axis
every plan grasps at its own angle. Written with the grasp geometry as symbols, one stabilization NLP, and
one compiled library of its inner Functions (:mod:`planner.nlp.compiled`), serve every grasp of a robot and
every target.

The geometry vector (:data:`GEOMETRY_SIZE` numbers, SI, 3×3 matrices column-major):

=========  ====================================================================
``[0]``      mass of the last link with the target [kg]
``[1:4]``    its COM in the last link's frame [m]
``[4:13]``   its inertia about that COM, last link's frame [kg·m²]
``[13]``     target mass [kg]
``[14:23]``  target inertia about its COM, target body frame [kg·m²]
``[23:26]``  target body origin (its COM) in the ee (grasp) frame, ``p_ee_target`` [m]
``[26:35]``  ``R_ee_target``
=========  ====================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.robot import BodyInertia, RobotModel

Array = NDArray[np.float64]

GEOMETRY_SIZE = 35


def compound_robot(scenario: Scenario, T_ee_target: Array) -> RobotModel:
    """The chaser with the target rigidly attached to its end-effector (target COM = body origin)."""
    t = scenario.target
    payload = BodyInertia(t.mass_kg, np.zeros(3), t.inertia_body_kg_m2)
    return scenario.robot.with_payload(payload, T_ee_target)


def grasp_geometry(scenario: Scenario, T_ee_target: Array) -> Array:
    """The geometry vector (module docstring) of grasping the scenario's target at ``T_ee_target`` (4×4)."""
    last = compound_robot(scenario, T_ee_target).inertias[-1]
    t = scenario.target
    T = np.asarray(T_ee_target, dtype=float)
    return np.concatenate([[last.mass_kg], last.com_body_m, last.inertia_com_kg_m2.ravel(order="F"),
                           [t.mass_kg], np.asarray(t.inertia_body_kg_m2, dtype=float).ravel(order="F"),
                           T[:3, 3], T[:3, :3].ravel(order="F")])


@dataclass(frozen=True)
class GraspGeometry:
    """The pieces of a symbolic (SX or MX) geometry vector; see the module docstring."""

    last_link: BodyInertia  # the compound's last link, symbolic mass, COM and inertia
    target_mass_kg: object
    target_inertia_body_kg_m2: object  # 3×3
    p_ee_target: object  # 3
    R_ee_target: object  # 3×3

    @staticmethod
    def unpack(vector: ca.SX | ca.MX) -> GraspGeometry:
        """Slice a symbolic geometry vector of :data:`GEOMETRY_SIZE` entries."""
        return GraspGeometry(BodyInertia(vector[0], vector[1:4], ca.reshape(vector[4:13], 3, 3)), vector[13],
                             ca.reshape(vector[14:23], 3, 3), vector[23:26], ca.reshape(vector[26:35], 3, 3))

    def compound(self, robot: RobotModel) -> RobotModel:
        """``robot`` with this geometry's last link: the compound, symbolic in the grasp geometry.

        Only its kinematics and inertias are meant for symbolic use (its pinocchio model stays the chaser's).
        """
        return replace(robot, inertias=(*robot.inertias[:-1], self.last_link))
