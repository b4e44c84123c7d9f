"""Physics of the two bodies.

Rotations, the chaser robot (pinocchio + CasADi), free-floating dynamics, the torque-free target and the
compound after the grasp.
"""
