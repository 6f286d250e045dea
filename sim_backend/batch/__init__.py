"""The batch engine: many runs, stepped by the behaviour's own source compiled with numba."""
