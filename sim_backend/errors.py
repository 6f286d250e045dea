"""The one error root of sim_backend."""


class SimError(Exception):
    """Base of every error sim_backend raises on purpose."""


class ScenarioError(SimError, ValueError):
    """A scenario is malformed: names the key and what would be right."""


class EngineError(SimError):
    """An engine cannot run what it was given (names what and why)."""


class CompileError(EngineError):
    """Behaviour source the batch engine cannot compile (a construct outside
    the subset it transforms): names the file, line and construct."""
