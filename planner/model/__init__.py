"""Physics of the two bodies.

Rotations, the chaser robot (its model, URDF reader, pinocchio boundary and CasADi kinematics),
free-floating dynamics, the target (its observed state, torque-free attitude motion, grasp-frame motion,
symbolic prediction) and the compound after the grasp.
"""
