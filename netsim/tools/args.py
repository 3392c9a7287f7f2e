"""Command-line parsers whose usage errors read as every other bad input does.

argparse prints its usage block before an error, three lines or more; a user's script or a
sweep's log then holds a block where one line says what was wrong. :class:`Parser` prints
``PROG: error: MESSAGE (PROG --help lists the options)`` on stderr, one line, and exits with
status 2, before anything is written. Its sub-command parsers (:class:`SubcommandParser`)
name themselves in every error, an unknown option's included.
"""

from __future__ import annotations

import argparse
import re
from typing import Any, NoReturn

from netsim.errors import did_you_mean

# Every number a float option takes, with a minus: argparse's own test knows only "-80" and
# "-.5", so "--sensitivity-dbm -8e1" or "-inf" read as an unknown option and left the
# option without its value.
NEGATIVE_NUMBER = re.compile(r"^-((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|inf|infinity|nan)$", re.IGNORECASE)


class Parser(argparse.ArgumentParser):
    """:class:`argparse.ArgumentParser` with one-line usage errors (module notes), and every
    negative number (``-8e1``, ``-inf``) read as a value, not an option."""

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        line = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {line} ({self.prog} --help lists the options)\n")

    def add_subparsers(self, **kwargs: Any) -> Any:
        kwargs.setdefault("parser_class", SubcommandParser)
        self.subcommands = super().add_subparsers(**kwargs)
        return self.subcommands


class SubcommandParser(Parser):
    """A sub-command's parser (``netsim run``): an option it does not know is refused in its
    own name, as a bad value to one of its options is. argparse leaves a sub-command's
    unknown options to the top parser, whose error names the program alone."""

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> tuple[Any, list[str]]:
        namespace, extras = super().parse_known_args(args, namespace)
        if extras:
            options = [o for o in self._option_string_actions if o.startswith("--")]
            typed = [e.split("=", 1)[0] for e in extras if e.startswith("--")]
            meant = next((m for m in (did_you_mean(t, options) for t in typed) if m), "")
            self.error(f"unrecognized arguments: {' '.join(extras)}{meant}")
        return namespace, extras
