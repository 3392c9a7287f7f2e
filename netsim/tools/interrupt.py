"""Ctrl-C (and SIGTERM) in the ``netsim`` command: the note that the user interrupted it, and the one
line and exit status 130 that say so (module notes of :mod:`netsim.tools.command`). Apart
from the command and the modules that give a run up, so that both may ask it."""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from netsim.errors import keyboard_interrupt_in

INTERRUPTED_LINE = "netsim: interrupted; nothing written"
EXIT_INTERRUPTED = 130
_INTERRUPTED = False


def on_sigint(signum: int, frame: object) -> None:
    global _INTERRUPTED
    _INTERRUPTED = True
    raise KeyboardInterrupt


def interrupted(exc: BaseException | None = None) -> bool:
    """Whether the user interrupted the command: Ctrl-C was pressed (in the command's own
    process), or ``exc`` is, or was raised while handling or because of, a
    ``KeyboardInterrupt``."""
    return keyboard_interrupt_in(exc) is not None or _INTERRUPTED


class KeptOnInterrupt(KeyboardInterrupt):
    """Ctrl-C after the command's results were put in place: they are kept, and the one
    line (``args[0]``) says what is there."""


@contextmanager
def kept_if_interrupted(line: str) -> Iterator[None]:
    """Within, the command's results are in place: an interrupt becomes :class:`KeptOnInterrupt`
    with ``line``, not the line that says nothing was written."""
    try:
        yield
    except BaseException as exc:
        if isinstance(exc, KeptOnInterrupt) or not interrupted(exc):
            raise
        raise KeptOnInterrupt(line) from None


@contextmanager
def ignoring_interrupts() -> Iterator[None]:
    """Ctrl-C held off within: one that comes meanwhile is dropped, so that what runs within
    (files moved into place, the line that reports an interrupt) is done whole. (Off the main
    thread, where no handler can be set, nothing changes.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    kept = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in kept.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


def exit_interrupted() -> None:
    """Say so in one line and end the process with status 130, at once: nothing else runs
    (the run directory was already given up by the handlers the interrupt went through)."""
    try:
        print(INTERRUPTED_LINE, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # a closed stream: the status still tells
        pass
    os._exit(EXIT_INTERRUPTED)
