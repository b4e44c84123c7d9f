"""NLP plumbing shared by the phases.

B-splines and the phases' parameter layouts, costs, compiled CasADi Functions, IPOPT set-up, the feasibility
stop and constraint back-offs, named vector layouts (``w``, ``p``, ``g``) and solve outcomes.
"""
