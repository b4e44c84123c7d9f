"""``lutgen build``: the parallel, resumable sweep of a grid, each point in a child process with a hard time limit."""
