"""The run's record: typed tables that become pandas DataFrames once, at the end.

Components append typed records (named tuples) to named tables. Components whose output
is a summary rather than a stream of records (counters, say) register a function that
builds their frame at the end.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pandas as pd
from pandas.api.types import is_string_dtype, pandas_dtype

from netsim.errors import NetsimInputError


class Trace:
    def __init__(self) -> None:
        self._records: dict[str, tuple[type, list]] = {}
        self._frame_builders: dict[str, Callable[[], pd.DataFrame]] = {}
        # Who registered each table, for messages about it: the configuration key that
        # chose the model (a user's model writes through written_by; netsim's own do not).
        self.owners: dict[str, str] = {}
        self._owner: str | None = None

    def written_by(self, owner: str) -> Trace:
        """This trace as the model ``owner`` writes it: the same tables, each it registers
        first recorded as its own in :attr:`owners`."""
        view = copy.copy(self)  # shares the tables and their owners
        view._owner = owner
        return view

    def _claim(self, name: str) -> None:
        if self._owner is not None:
            self.owners.setdefault(name, self._owner)

    def declare(self, name: str, record_type: type) -> None:
        """Declare table ``name`` of ``record_type`` records (so it exists even if empty)."""
        self._claim(name)
        self._records.setdefault(name, (record_type, []))

    def emit(self, name: str, record: tuple) -> None:
        rows = self._records.get(name)
        if rows is None:
            self.declare(name, type(record))
            rows = self._records[name]
        rows[1].append(record)

    def add_frame(self, name: str, build: Callable[[], pd.DataFrame]) -> None:
        """Register a table computed at the end of the run."""
        self._claim(name)
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


# The dtype pandas gives text of its own accord (str from pandas 3, object before): a
# table's text column as a Parquet file read back holds it.
TEXT_DTYPE = pd.Series(["text"]).dtype


def frame_dtypes(schema: Mapping[str, str]) -> dict[str, Any]:
    """``schema``'s dtypes as a frame holds them: its text ("object") as :data:`TEXT_DTYPE`."""
    return {column: TEXT_DTYPE if dtype == "object" else dtype for column, dtype in schema.items()}


def empty_table(schema: Mapping[str, str]) -> pd.DataFrame:
    """A table without rows, with the columns and dtypes of ``schema``."""
    return pd.DataFrame({column: pd.Series(dtype=dtype) for column, dtype in frame_dtypes(schema).items()})


def as_read_back(frame: pd.DataFrame, schema: Mapping[str, str]) -> pd.DataFrame:
    """``frame`` with the dtypes its Parquet file has read back: a declared text column held
    as object becomes :data:`TEXT_DTYPE` (from pandas 3 its None, missing, NaN); a table
    without rows takes every declared dtype."""
    dtypes = frame_dtypes(schema)
    if len(frame) == 0:
        casts = {c: t for c, t in dtypes.items() if c in frame.columns}
    else:
        casts = {c: t for c, t in dtypes.items() if t is TEXT_DTYPE and c in frame.columns and frame[c].dtype == object}
    return frame.astype(casts) if casts else frame


def conform(frame: pd.DataFrame, schema: Mapping[str, str], who: str, name: str) -> pd.DataFrame:
    """Table ``name`` as ``schema`` declares it: its columns in the declared order, each of
    its declared dtype; a frame with neither rows nor columns is the declared empty table.

    A column whose values all cast without change (int64 to float64) is cast, as a script
    reading the table expects the declared type. Columns missing or not declared, or
    written in a dtype that could change values if cast, are refused in one line naming
    ``who`` (the key that chose the model) and the table."""
    if len(frame) == 0 and len(frame.columns) == 0:
        return empty_table(schema)
    _check_columns(frame, schema, who, name)
    if list(frame.columns) != list(schema):
        frame = frame[list(schema)]
    casts = {
        column: _cast(frame[column].dtype, dtype, f"{who}: table {name!r}, column {column!r}")
        for column, dtype in schema.items()
    }
    casts = {column: to for column, to in casts.items() if to is not None}
    return frame.astype(casts) if casts else frame


def _check_columns(frame: pd.DataFrame, schema: Mapping[str, str], who: str, name: str) -> None:
    missing = [str(c) for c in schema if c not in frame.columns]
    extra = [str(c) for c in frame.columns if c not in schema]
    if missing or extra:
        told = [f"missing {', '.join(missing)}"] if missing else []
        told += [f"not declared {', '.join(extra)}"] if extra else []
        raise NetsimInputError(f"{who}: table {name!r} has other columns than its plugin declares ({'; '.join(told)})")


def _cast(got: Any, declared: str, where: str) -> Any:
    """The dtype a column written as ``got`` is cast to (None: it is as declared); one that
    could change values is refused, naming the column (``where``)."""
    want = pandas_dtype(declared)
    # Text is "object" in a declaration, and object or pandas' str in a frame.
    if got == want or (is_string_dtype(want) and is_string_dtype(got)):
        return None
    if isinstance(got, np.dtype) and isinstance(want, np.dtype) and np.can_cast(got, want, "safe"):
        return want
    raise NetsimInputError(
        f"{where} is written as {got}, declared {declared}: declare what it writes, or write what it declares"
    )
