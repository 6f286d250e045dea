"""touchswarm for notebooks: `import touchswarm` (docs/python-api.md).

A thin facade: everything lives in sim_backend.api; this module only
re-exports it under the project's name.
"""

from sim_backend.api import Result, run, sweep, version

__version__ = version()
__all__ = ["Result", "run", "sweep", "__version__"]
