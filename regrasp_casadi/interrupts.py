"""Ctrl-C while planning: finish the current solve, then stop with the plan so far (status "interrupted").

CasADi runs IPOPT inside one C++ call that swallows a KeyboardInterrupt raised by Python's default SIGINT
handler, so the first Ctrl-C used to be lost and planning went on. `deferred_interrupts` replaces the
handler for the duration of a plan: the first SIGINT only sets a flag, which the planner reads between
its steps (a solve takes milliseconds to a few seconds); a second SIGINT raises KeyboardInterrupt at once.
Outside the main thread (where Python cannot install signal handlers) the flag never sets.

    >>> with deferred_interrupts() as stop:
    ...     while not stop.requested: ...
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = ["InterruptRequest", "deferred_interrupts"]


class InterruptRequest:
    """Whether a SIGINT arrived since `deferred_interrupts` was entered."""

    def __init__(self) -> None:
        self.requested = False


@contextlib.contextmanager
def deferred_interrupts() -> Iterator[InterruptRequest]:
    """Defer the first SIGINT to the caller (`InterruptRequest.requested`); restore the handler on exit."""
    request = InterruptRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return
    previous = signal.getsignal(signal.SIGINT)
    restore = previous if previous is not None else signal.default_int_handler

    def on_sigint(signum, frame) -> None:
        if request.requested:  # the second Ctrl-C: stop now
            signal.signal(signal.SIGINT, restore)
            raise KeyboardInterrupt
        request.requested = True

    signal.signal(signal.SIGINT, on_sigint)
    try:
        yield request
    finally:
        signal.signal(signal.SIGINT, restore)
