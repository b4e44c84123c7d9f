"""How much tighter than the true limits the NLPs are, so that what holds at the via points also holds
between them (the dense verification checks every ≤ 0.02 s; the NLPs only at k via points).

Between two via points a constraint can overshoot by about (spacing²/8)·(its second time derivative);
with via points ≤ 1 s apart and the smooth cubic B-splines these back-offs cover the measured overshoots
(joint position ~1e-3 rad, distance ~1e-2 m, grasp torque ~5 N·m at 2.25 s spacing; far less at 1 s).
"""

JOINT_POSITION_RAD = 0.01  # ≈ 0.6°
JOINT_VELOCITY_FRACTION = 0.97
COLLISION_M = 0.005
WRENCH_FRACTION = 0.93
