"""Collision geometry: the scene's layout, the handle-contact rule, and the NLPs' exact signed distances.

The layout (bodies, shapes, pairs) and the contact rule are the specification both the NLPs and verify read;
the closed-form engine, the scene that groups shapes into bodies and the CasADi callback are the NLPs' alone.
"""
