"""touchswarm for notebooks: `import touchswarm` (docs/python-api.md).

A thin facade: everything lives in sim_backend.api; this module only
re-exports it under the project's name.
"""

from typing import Any

from sim_backend.api import Result, run, sweep
from sim_backend.version import version

__all__ = ["Result", "run", "sweep", "__version__"]   # noqa: F822 - __version__: __getattr__


def __getattr__(name: str) -> Any:
    # __version__ read when asked for: the installed version comes from
    # importlib.metadata, which `import touchswarm` need not load
    if name == "__version__":
        return version()
    raise AttributeError(f"module 'touchswarm' has no attribute {name!r}")
