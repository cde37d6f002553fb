"""Base exception of the library: the CLI turns these into one-line messages, not tracebacks."""


class Sim4EndoRError(Exception):
    """A user-facing error: the message names the bad input and what would fix it."""


def caused_by_interrupt(error: BaseException) -> bool:
    """Whether ``error`` is a Ctrl-C, or was raised while one was being handled.

    Libraries turn an interrupt into other exceptions on its way up: MuJoCo's extension,
    initialising, into an ImportError raised from it; TorchRL's collector into a RuntimeError
    about a tensordict's truth value, raised while the interrupt unwound. The chain of causes
    and contexts still holds the KeyboardInterrupt.
    """
    seen: set[int] = set()
    current: BaseException | None = error
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False
