"""The ``netsim`` console script.

Loading the command (numpy, pandas, pyarrow, the engine) makes hundreds of thousands of
long-lived objects and no garbage, and the garbage collector would walk them again and
again as they are made. So the collector is paused while they load, then
:func:`netsim.tools.cli.command` freezes them out of its passes for good. This module
imports nothing heavy itself, and neither does importing the ``netsim`` package.
"""

from __future__ import annotations

import gc


def command() -> None:
    """The ``netsim`` command (:func:`netsim.tools.cli.command`), its libraries loaded with
    the collector paused."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        from netsim.tools import cli
    finally:
        if was_enabled:
            gc.enable()
    cli.command()
