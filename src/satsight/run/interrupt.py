"""Stopping a run on Ctrl-C: the first one finishes the frames in flight, a second one
interrupts at once."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager


class StopFlag:
    """Set when the user asks the run to stop (Ctrl-C): finish the frames in flight."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def set(self) -> None:
        self._event.set()

    def is_set(self) -> bool:
        return self._event.is_set()


@contextmanager
def stop_on_sigint(flag: StopFlag) -> Iterator[None]:
    """First Ctrl-C sets ``flag`` (the run stops after the frames in flight); a second
    one interrupts at once (committed frames are kept either way)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame) -> None:
        if flag.is_set():
            raise KeyboardInterrupt
        flag.set()

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore Ctrl-C while local worker or render processes start: they inherit the
    ignored signal, so a Ctrl-C in the terminal reaches only this process, which stops the
    run after the frames in flight (the processes would otherwise die with their frames)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
