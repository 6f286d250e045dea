"""The one error root of sim_backend."""


class SimError(Exception):
    """Base of every error sim_backend raises on purpose."""


class ScenarioError(SimError, ValueError):
    """A scenario is malformed: names the key and what would be right."""


class EngineError(SimError):
    """An engine cannot run what it was given (names what and why)."""


class CompileError(EngineError):
    """Behaviour source the batch engine cannot compile (a construct or an
    attribute type outside what it transforms): names it and where."""
