"""Command-line parsers whose usage errors read as every other bad input does.

argparse prints its usage block before an error, three lines or more; a user's script or a
sweep's log then holds a block where one line says what was wrong. :class:`Parser` prints
``PROG: error: MESSAGE (PROG --help lists the options)`` on stderr, one line, and exits with
status 2, before anything is written. Its sub-command parsers are of the same class.
"""

from __future__ import annotations

import argparse
from typing import NoReturn


class Parser(argparse.ArgumentParser):
    """:class:`argparse.ArgumentParser` with one-line usage errors (module notes)."""

    def error(self, message: str) -> NoReturn:
        line = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {line} ({self.prog} --help lists the options)\n")
