"""The one error root of bridge, with typed subclasses."""


class BridgeError(Exception):
    """Base of every error bridge raises on purpose."""


class UsageError(BridgeError, ValueError):
    """Bad input from the command line: the CLI exits with status 2."""
