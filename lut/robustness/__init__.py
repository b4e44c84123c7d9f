"""``lutgen robustness``: how much observation error a plan absorbs (error model, parallel runs, statistics, report)."""
