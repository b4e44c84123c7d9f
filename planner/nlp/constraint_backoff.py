"""How much tighter than the true limits the NLPs are, so that what holds at the via points also holds
between them (the dense verification checks every ≤ 0.02 s; the NLPs only at k via points).

Between two via points a constraint can overshoot by about (spacing²/8)·(its second time derivative).
Measured on scenario II's stabilization: the grasp torque bulges ~0.9 N·m between via points 1.5 s apart
(the gyroscopic term ω × Iω of a 7000 kg·m² target curves it), a passing solar panel dips a distance by
~3.5 cm over 1.5 s; at 0.75 s spacing a quarter of that, which these back-offs cover.

The wrench back-off is 5 % (0.5 N·m of scenario II's 10 N·m): at the scenario's 0.75 s spacing the peak
of |grasp torque| sampled every 0.01 s exceeded the via-point peak by 0.001-0.16 N·m on five solved grasps.
It was 10 %, which left a feasible set so thin (the braking that keeps the swinging target clear of the
chaser needs ~9 N·m) that IPOPT's limited-memory iterations wandered: the CI table's 4 points took 311 s
(one 294 s) at 10 % and 30 s at 5 %, all feasible; the plan of the scenario's default state 833
iterations against 43.
"""

JOINT_POSITION_RAD = 0.01  # ≈ 0.6°
JOINT_VELOCITY_FRACTION = 0.97
COLLISION_M = 0.02
WRENCH_FRACTION = 0.95
