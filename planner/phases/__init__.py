"""The three phases of a grasp plan (paper §4): approach NLP and its initial guess, tracking IK, stabilization NLP."""
