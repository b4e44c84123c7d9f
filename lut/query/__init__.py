"""``lutgen query``: an observed target state to a verified plan, from a table."""
