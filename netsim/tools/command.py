"""The ``netsim`` console script.

Loading the command (numpy, pandas, pyarrow, the engine) makes hundreds of thousands of
long-lived objects and no garbage, and the garbage collector would walk them again and
again as they are made. So the collector is paused while they load, then
:func:`netsim.tools.cli.command` freezes them out of its passes for good. This module
imports nothing heavy itself, and neither does importing the ``netsim`` package.

Ctrl-C is one line and exit status 130 wherever it lands: while the libraries load, in
the run, inside a compiled (numba) call, while the tables are written. The command's own
handler of SIGINT notes the interrupt before raising ``KeyboardInterrupt`` as Python's
does; a compiled call or a C library that the ``KeyboardInterrupt`` crosses may turn it
into another exception (a ``SystemError`` whose context is the interrupt, or none at
all), and the note tells such an exception for what it is (:func:`interrupted`).
"""

from __future__ import annotations

import gc
import os
import signal
import sys

INTERRUPTED_LINE = "netsim: interrupted; nothing written"
EXIT_INTERRUPTED = 130
_INTERRUPTED = False


def _on_sigint(signum: int, frame: object) -> None:
    global _INTERRUPTED
    _INTERRUPTED = True
    raise KeyboardInterrupt


def interrupted(exc: BaseException | None = None) -> bool:
    """Whether the user interrupted the command: Ctrl-C was pressed (in the command's own
    process), or ``exc`` is, or was raised while handling or because of, a
    ``KeyboardInterrupt``."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return _INTERRUPTED


def exit_interrupted() -> None:
    """Say so in one line and end the process with status 130, at once: nothing else runs
    (the run directory was already given up by the handlers the interrupt went through)."""
    try:
        print(INTERRUPTED_LINE, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # a closed stream: the status still tells
        pass
    os._exit(EXIT_INTERRUPTED)


def command() -> None:
    """The ``netsim`` command (:func:`netsim.tools.cli.command`), its libraries loaded with
    the collector paused, Ctrl-C one line and exit status 130 wherever it lands."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not ignored by the parent
        signal.signal(signal.SIGINT, _on_sigint)
    try:
        was_enabled = gc.isenabled()
        gc.disable()
        try:
            from netsim.tools import cli
        finally:
            if was_enabled:
                gc.enable()
        cli.command()
    except BaseException as exc:
        if not interrupted(exc):
            raise
        exit_interrupted()
