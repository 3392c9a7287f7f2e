"""What this machine has: its memory, for the checks that refuse a run that cannot fit in
it before any work."""

from __future__ import annotations

import os


def machine_memory_bytes() -> int | None:
    """The machine's physical memory, None where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None


def gib(nbytes: float) -> str:
    """``nbytes`` in GiB, as the refusals print it."""
    value = nbytes / 2**30
    return f"{value:,.1f}" if value < 1e6 else f"{value:.2g}"
