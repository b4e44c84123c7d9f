"""NLP plumbing shared by the phases.

B-splines, costs, compiled CasADi Functions, IPOPT set-up, named decision/constraint layouts.
"""
