"""Physics of the two bodies.

Rotations, the chaser robot (pinocchio + CasADi), free-floating dynamics, the target (its observed state,
torque-free attitude motion, grasp-frame motion, symbolic prediction) and the compound after the grasp.
"""
