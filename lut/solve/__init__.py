"""Solving one target state in a child process with a hard time limit: what a build and a query's refine share."""
