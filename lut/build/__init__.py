"""``lutgen build``: the parallel, resumable sweep of a grid, one child process per point."""
