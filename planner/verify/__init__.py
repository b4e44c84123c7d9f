"""Dense verification of a plan, a second opinion that shares no code path with the NLPs for what it checks."""
