"""Errors that reach users. The CLI turns these into one line and exit status 2."""

import os
from collections.abc import Iterable
from typing import Any


class NetsimInputError(Exception):
    """Bad input from the user: a configuration value, a file, a command-line option."""


def setting(key: str, value: object) -> str:
    """``key = value`` as messages name a configuration setting."""
    # A key read from a file may hold any character: keep the message on one line.
    shown = key if key.isprintable() else repr(key)
    # A truth value as the configuration file spells it.
    given = str(value).lower() if isinstance(value, bool) else repr(value)
    return f"{shown} = {given}"


class ConfigError(NetsimInputError):
    """A configuration value that is not allowed.

    The message names the key, the value given and what is allowed, so the user can fix
    the file without reading code.
    """

    # The file that set the key, where it is one (netsim.config.load), named first.
    source: str = ""

    def __init__(self, key: str, value: object, allowed: str):
        self.key = key
        self.value = value
        self.allowed = allowed
        # Its arguments make it anew: SimPy copies an error raised in a process as
        # type(e)(*e.args), and pickling (a worker process's error) does the same.
        super().__init__(key, value, allowed)

    def __str__(self) -> str:
        where = f"{self.source}: " if self.source else ""
        return f"{where}{setting(self.key, self.value)}: {self.allowed}"


def not_a_file(path: str | os.PathLike) -> str:
    """Why ``path``, expected to be a file, is not one: ``"is a directory, not a file"``,
    ``"is not a regular file"`` (a pipe, a device) or ``"no such file"``; the words every
    reader of a user's file gives."""
    if os.path.isdir(path):
        return "is a directory, not a file"
    return "is not a regular file" if os.path.exists(path) else "no such file"


def needs_extra(who: str, libraries: Iterable[str], extra: str) -> str:
    """What ``who`` says when ``libraries`` of the optional extra ``extra`` (pyproject.toml)
    are not installed: which, and the line that installs them."""
    return (
        f"{who} needs {' and '.join(libraries)}, of the optional extra {extra!r}: "
        f"pip install 'netsim-robots[{extra}]' (in a clone: pip install -e '.[{extra}]')"
    )


def listed(items: Iterable[Any], most: int = 10) -> str:
    """At most ``most`` of ``items``, comma-separated, and how many more: a message names a
    few of many, not all."""
    names = [str(item) for item in items]
    shown = ", ".join(names[:most])
    return f"{shown} and {len(names) - most} more" if len(names) > most else shown


def keyboard_interrupt_in(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The ``KeyboardInterrupt`` that ``exc`` is, or was raised while handling or because
    of (numba's dispatcher wraps one raised inside a compiled call in ``SystemError``)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` naming the known name closest to a misspelt ``name`` (case
    aside), or nothing where none is close."""
    import difflib

    by_fold = {k.casefold(): k for k in known}
    close = difflib.get_close_matches(name.casefold(), list(by_fold), n=1, cutoff=0.75)
    return f" (did you mean {by_fold[close[0]]!r}?)" if close else ""
