"""Base exception of the library: the CLI turns these into one-line messages, not tracebacks."""


class Sim4EndoRError(Exception):
    """A user-facing error: the message names the bad input and what would fix it."""
