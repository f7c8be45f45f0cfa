"""SIGINT/SIGTERM as a request to stop, shared by node processes and the runner.

Both must finish what they are doing before they stop (a node its callback,
the runner its nodes), so neither may die on the signal or let rclpy shut
its context down under a running callback.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from typing import Any

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def catch_stop_signals(
    received: list[int], on_stop: Callable[[int], None] | None = None
) -> dict[int, Any]:
    """Append SIGINT/SIGTERM to ``received`` instead of acting on them.

    Only in the main thread (elsewhere Python cannot install handlers:
    nothing is changed). ``on_stop(signum)``: called too (a node's hard
    deadline, :func:`hard_deadline`). Returns the previous handlers for
    :func:`restore_handlers`.
    """
    if threading.current_thread() is not threading.main_thread():
        return {}

    def record(signum: int, _frame: object) -> None:
        received.append(signum)
        if on_stop is not None:
            on_stop(signum)

    return {sig: signal.signal(sig, record) for sig in STOP_SIGNALS}


def restore_handlers(previous: dict[int, Any]) -> None:
    """Put back the handlers :func:`catch_stop_signals` replaced."""
    for sig, handler in previous.items():
        signal.signal(sig, handler)


def hard_deadline(seconds: float) -> Callable[[int], None]:
    """An ``on_stop`` that ends the process ``seconds`` after the first stop signal, whatever it does.

    A node asked to stop finishes its callback and its spin loop; one whose
    loop does not end (a callback that never returns, a thread that never
    lets it run) is ended by ``os._exit(128 + signum)`` from a thread of its
    own, so that SIGTERM to a node always ends it.
    """
    import os
    import time

    started: list[bool] = []

    def arm(signum: int) -> None:
        if started:
            return
        started.append(True)

        def end() -> None:
            time.sleep(seconds)
            os._exit(128 + signum)

        threading.Thread(target=end, name="stop-deadline", daemon=True).start()

    return arm
