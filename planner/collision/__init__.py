"""Collision geometry and exact signed distances for the NLPs.

Shapes grouped into bodies, the scenario's pairs, the handle-contact rule, the CasADi callback.
"""
