"""The three phases of a grasp plan (paper §4): approach NLP and its initial guess, tracking IK, stabilization NLP.

Each NLP phase is a problem module (the symbolic NLP, built once per scenario) and a ``*_solve`` module (its
starts and IPOPT runs for one target state or one grasp).
"""
