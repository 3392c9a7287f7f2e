"""The garbage collector paused while the heavy libraries load.

Importing the engine and its libraries (numpy, pandas, pyarrow, numba and its registries)
makes hundreds of thousands of long-lived objects and no garbage, and Python's collector
walks them again and again as they are made. So the collector is paused while they load
and resumed as it was (a user who had switched it off keeps it off). In a process of its
own (the command line: :func:`own_process`) netsim also freezes what has been loaded
(``gc.freeze``), so that the collector never walks it again: about 0.1 s of a 1,000-robot
run's 1.7 s process. A library user's process is left unfrozen: what loaded is moved to
the collector's oldest generation (frozen and thawed at once), where a young-generation pass
would otherwise walk all of it as soon as the collector resumes.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

_freeze = False


def own_process() -> None:
    """The process is netsim's alone (the command line): freeze what is loaded now, and
    after each :func:`paused` block, out of the collector's passes."""
    global _freeze
    _freeze = True
    gc.freeze()


@contextmanager
def paused() -> Iterator[None]:
    """Pause the garbage collector for the block; resume it as it was."""
    collecting = gc.isenabled()
    # (Counting the frozen objects walks them all: not in the command line's process.)
    thaw = not _freeze and gc.get_freeze_count() == 0
    gc.disable()
    try:
        yield
    finally:
        if _freeze:
            gc.freeze()
        elif thaw:
            # What loaded (with every object tracked before) goes straight to the oldest
            # generation, nothing left frozen: otherwise the first allocation after the
            # pause walks all of it as young objects (about 30 ms after importing netsim),
            # and again one generation up; cycles among them are still found by the next
            # full pass. Where the user had frozen objects, unfreezing would thaw them.
            gc.freeze()
            gc.unfreeze()
        if collecting:
            gc.enable()
