"""The run's record: typed tables that become pandas DataFrames once, at the end.

Components append typed records (named tuples) to named tables. Components whose output
is a summary rather than a stream of records (counters, say) register a function that
builds their frame at the end.
"""

from __future__ import annotations

from collections.abc import Callable

import pandas as pd


class Trace:
    def __init__(self) -> None:
        self._records: dict[str, tuple[type, list]] = {}
        self._frame_builders: dict[str, Callable[[], pd.DataFrame]] = {}

    def declare(self, name: str, record_type: type) -> None:
        """Declare table ``name`` of ``record_type`` records (so it exists even if empty)."""
        self._records.setdefault(name, (record_type, []))

    def emit(self, name: str, record: tuple) -> None:
        rows = self._records.get(name)
        if rows is None:
            self.declare(name, type(record))
            rows = self._records[name]
        rows[1].append(record)

    def add_frame(self, name: str, build: Callable[[], pd.DataFrame]) -> None:
        """Register a table computed at the end of the run."""
        self._frame_builders[name] = build

    def frame(self, name: str) -> pd.DataFrame:
        if name in self._frame_builders:
            return self._frame_builders[name]()
        record_type, rows = self._records[name]
        return pd.DataFrame(rows, columns=list(record_type._fields))  # type: ignore[attr-defined]  # a NamedTuple

    def names(self) -> list[str]:
        return sorted(set(self._records) | set(self._frame_builders))

    def frames(self) -> dict[str, pd.DataFrame]:
        return {name: self.frame(name) for name in self.names()}
