"""How much tighter than the true limits the NLPs are, so that what holds at the via points also holds
between them (the dense verification checks every ≤ 0.02 s; the NLPs only at k via points).

Between two via points a constraint can overshoot by about (spacing²/8)·(its second time derivative): the
grasp torque bulges between via points (the gyroscopic term ω × Iω of a large target curves it), a passing
solar panel dips a distance. At the scenarios' 0.75 s spacing these back-offs cover it. The wrench back-off
is no larger than that: a larger one leaves so thin a feasible set (the braking that keeps the swinging
target clear of the chaser needs most of the torque limit) that IPOPT's limited-memory iterations wander.
"""

from __future__ import annotations

JOINT_POSITION_RAD = 0.01  # [rad] ≈ 0.6°, inside each joint limit
JOINT_VELOCITY_FRACTION = 0.97  # of each joint-rate limit
COLLISION_M = 0.02  # [m] above each required clearance
WRENCH_FRACTION = 0.95  # of the grasp torque and force limits
