"""The ``netsim`` console script.

Loading the command (numpy, pandas, pyarrow, the engine) makes hundreds of thousands of
long-lived objects and no garbage, and the garbage collector would walk them again and
again as they are made. So the collector is paused while they load, then
:func:`netsim.tools.cli.command` freezes them out of its passes for good. This module
imports nothing heavy itself, and neither does importing the ``netsim`` package.

Ctrl-C (or SIGTERM, as a timeout or a batch scheduler sends) is one line and exit status
130 wherever it lands: while the libraries load, in
the run, inside a compiled (numba) call, while the tables are written. The command's own
handler of SIGINT notes the interrupt before raising ``KeyboardInterrupt`` as Python's
does; a compiled call or a C library that the ``KeyboardInterrupt`` crosses may turn it
into another exception (a ``SystemError`` whose context is the interrupt, or none at
all), and the note tells such an exception for what it is (:func:`interrupted`).
"""

from __future__ import annotations

import gc
import signal

from netsim.tools.interrupt import EXIT_INTERRUPTED, INTERRUPTED_LINE, exit_interrupted, interrupted, on_sigint

__all__ = ["EXIT_INTERRUPTED", "INTERRUPTED_LINE", "command", "exit_interrupted", "interrupted"]


def command() -> None:
    """The ``netsim`` command (:func:`netsim.tools.cli.command`), its libraries loaded with
    the collector paused, Ctrl-C one line and exit status 130 wherever it lands."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not ignored by the parent
        signal.signal(signal.SIGINT, on_sigint)
    # A timeout or a batch scheduler ends a command with SIGTERM: given up as Ctrl-C gives it
    # up (nothing written), where Python's default would leave the run directory behind.
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, on_sigint)
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
        # The command's own exit (after it said what an interrupt left) is not to be reported again.
        if isinstance(exc, SystemExit) or not interrupted(exc):
            raise
        exit_interrupted()
