"""SIGINT/SIGTERM as a request to stop, shared by node processes and the runner.

Both must finish what they are doing before they stop (a node its callback,
the runner its nodes), so neither may die on the signal or let rclpy shut
its context down under a running callback.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def catch_stop_signals(received: list[int]) -> dict[int, Any]:
    """Append SIGINT/SIGTERM to ``received`` instead of acting on them.

    Only in the main thread (elsewhere Python cannot install handlers:
    nothing is changed). Returns the previous handlers for
    :func:`restore_handlers`.
    """
    if threading.current_thread() is not threading.main_thread():
        return {}

    def record(signum: int, _frame: object) -> None:
        received.append(signum)

    return {sig: signal.signal(sig, record) for sig in STOP_SIGNALS}


def restore_handlers(previous: dict[int, Any]) -> None:
    """Put back the handlers :func:`catch_stop_signals` replaced."""
    for sig, handler in previous.items():
        signal.signal(sig, handler)
