"""Errors of the links: one root, with the two kinds a caller tells apart:
a timeout (also a TimeoutError; the host drops the tick's frames and goes
on) and a malformed link URL (also a UsageError; the CLI exits 2). A link
that cannot be opened or fails in use, and host and robots without a shared
key file, are a LinkError whose one-line message says which."""

from __future__ import annotations

from bridge.errors import BridgeError, UsageError


class LinkError(BridgeError):
    """Base of every error a link raises."""


class LinkTimeoutError(LinkError, TimeoutError):
    """An expected frame did not arrive in time."""


class LinkURLError(LinkError, UsageError):
    """A link URL is malformed or has an unknown option; names the expected form."""
