"""Parameters: small frozen dataclasses, validated when they are made.

Every part of a run that has parameters (the world, the channel, each model) declares them
as a frozen dataclass derived from :class:`Params`, one field per configuration key, each
made with :func:`param` (its default, a check and its meaning with the unit). However the
object is made (from a file, from ``--set`` or in Python), ``__post_init__`` coerces each
value as TOML gives it (an integer is accepted for a float, a name for a choice), checks
it, derives the defaults that follow another key (``tau_s = 3 ack_period_s``) and checks
the rules between the section's keys. A bad value raises :class:`~netsim.errors.ConfigError`
naming the key (``section.name``), the value and what is allowed.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Beacon(Params):
...     section = "beacon"
...     period_s: float = param(1.0, positive, "period, s")
...     timeout_s: float = param(None, positive, "timeout, s", kind=float,
...                              derive=lambda p: 3 * p.period_s, rule="3 x period_s")
>>> Beacon(period_s=2).timeout_s
6.0
>>> Beacon(period_s=2).replace(period_s=5).timeout_s
15.0
>>> Beacon(period_s=-1)
Traceback (most recent call last):
...
netsim.errors.ConfigError: beacon.period_s = -1.0: must be > 0 (period, s)
"""

from __future__ import annotations

import dataclasses
import enum
import math
import numbers
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from netsim.errors import ConfigError
from netsim.geometry import SPEED_OF_LIGHT_MPS, drivable

Check = Callable[[Any], "str | None"]
Coerce = Callable[[str, Any], Any]


def positive(v: float) -> str | None:
    return None if v > 0 else "must be > 0"


def non_negative(v: float) -> str | None:
    return None if v >= 0 else "must be >= 0"


def ttl_field(v: int) -> str | None:
    """A TTL as an IP header or a routing message carries it: one octet."""
    return None if 1 <= v <= 255 else "must be in 1 .. 255 (a TTL is one octet)"


# The largest frame a key may size: an 802.11 frame is under 8 KiB; past 2^31 bytes a count
# of frames times their size leaves the tables' 64-bit integers.
MAX_FRAME_BYTES = 2**31 - 1


def frame_size(v: int) -> str | None:
    """A frame's size in bytes: at least 1, at most :data:`MAX_FRAME_BYTES`."""
    return None if 1 <= v <= MAX_FRAME_BYTES else f"must be in 1 .. {MAX_FRAME_BYTES} (bytes of one frame)"


def speed(v: float) -> str | None:
    """A speed in m/s: finite, at least 0, and one a robot may be driven at
    (:func:`netsim.geometry.drivable`: no faster than light), so that a draw up to it never
    stops the run midway."""
    if not (math.isfinite(v) and v >= 0):
        return "must be a finite speed >= 0"
    return None if drivable((v, 0.0)) else f"must be at most {SPEED_OF_LIGHT_MPS:g} (m/s, no faster than light)"


def probability(v: float) -> str | None:
    return None if 0 <= v <= 1 else "must be a probability in [0, 1]"


def finite(check: Check) -> Check:
    """``check``, and finite."""

    def both(v: float) -> str | None:
        return check(v) or (None if math.isfinite(v) else "must be finite")

    return both


def param(
    default: Any,
    check: Check | None = None,
    doc: str = "",
    *,
    kind: type | None = None,
    coerce: Coerce | None = None,
    derive: Callable[[Any], Any] | None = None,
    rule: str = "",
    default_factory: Callable[[], Any] | None = None,
    schedules: str = "",
) -> Any:
    """A configuration key: its ``default``, a ``check`` (returns what is wrong, or None),
    its meaning ``doc`` (with the unit). The value's type is that of the default unless
    ``kind`` says otherwise; ``coerce(key, value)`` replaces the standard coercion;
    ``derive(params)`` gives the default from the other values when none is given (None),
    and ``rule`` says how, in words (``"3 x ack_period_s"``). ``schedules``: the key is a
    period (``_s``) or a rate (``_hz``) of events of each ``"robot"`` or of the ``"run"``,
    whose count :func:`check_schedules` bounds."""
    meta = {
        "check": check,
        "doc": doc,
        "kind": kind,
        "coerce": coerce,
        "derive": derive,
        "rule": rule,
        "schedules": schedules,
    }
    if default_factory is not None:
        return field(default_factory=default_factory, metadata=meta)
    return field(default=default, metadata=meta)


def coerce_value(key: str, value: Any, kind: type) -> Any:
    """``value`` as ``kind`` (bool, int, float, str or a str enum), or ConfigError."""
    # numpy's scalars are accepted as the Python numbers they stand for: a value computed in
    # a script (np.int64 from a sweep's array) is as good as one typed.
    if kind is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise ConfigError(key, value, "must be true or false")
        return bool(value)
    if kind is int:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
            raise ConfigError(key, value, "must be an integer")
        return int(value)
    if kind is float:
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise ConfigError(key, value, "must be a number")
        try:
            value = float(value)
        except OverflowError:
            raise ConfigError(key, value, "is too large for a number") from None
        if math.isnan(value):
            raise ConfigError(key, value, "must be a number, not NaN")
        return value
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        if isinstance(value, kind):
            return value
        allowed = "must be one of " + ", ".join(repr(m.value) for m in kind)
        if not isinstance(value, str):
            raise ConfigError(key, value, allowed)
        try:
            return kind(value)
        except ValueError:
            raise ConfigError(key, value, allowed) from None
    if not isinstance(value, str):
        raise ConfigError(key, value, "must be a string")
    return value


@dataclass(frozen=True)
class Params:
    """Base of every parameter dataclass (module notes). ``section`` names its
    configuration table; :meth:`check` holds the rules between its own keys."""

    section: ClassVar[str] = ""

    def __post_init__(self) -> None:
        derived = []
        for f in _keys(type(self)):
            value = getattr(self, f.name)
            if value is None and f.metadata.get("derive") is not None:
                derived.append(f)
                continue
            object.__setattr__(self, f.name, self._valid(f, value))
        for f in derived:
            object.__setattr__(self, f.name, self._valid(f, f.metadata["derive"](self)))
        object.__setattr__(self, "_derived", frozenset(f.name for f in derived))
        self.check()

    def _valid(self, f: dataclasses.Field, value: Any) -> Any:
        key = self.key(f.name)
        meta = f.metadata
        if meta.get("coerce") is not None:
            value = meta["coerce"](key, value)
        else:
            kind = meta.get("kind") or type(f.default if f.default is not dataclasses.MISSING else value)
            value = coerce_value(key, value, kind)
        check = meta.get("check")
        problem = check(value) if check is not None else None
        if problem:
            doc = meta.get("doc", "")
            raise ConfigError(key, value, problem + (f" ({doc})" if doc else ""))
        return value

    def check(self) -> None:
        """Rules between this section's keys (raise ConfigError); none by default."""

    def inputs(self) -> dict[str, str]:
        """The files (or folders) this section's model will read, by key: a run checks that
        they are there before it starts (a sweep, before its first run); none by default.
        Not checked when a configuration is only read (a finished run's, to draw it)."""
        return {}

    @classmethod
    def key(cls, name: str) -> str:
        """The configuration key of field ``name``: ``section.name``."""
        return f"{cls.section}.{name}" if cls.section else name

    @property
    def derived(self) -> frozenset[str]:
        """Fields whose value was derived from the others (not given)."""
        return self.__dict__.get("_derived", frozenset())

    def replace(self, **changes: Any) -> Params:
        """A copy with ``changes``; values that were derived are derived again unless given."""
        values = {name: getattr(self, name) for name in names(type(self)) if name not in self.derived}
        values.update(changes)
        return type(self)(**values)

    def items(self, derived: bool = True) -> Iterator[tuple[str, Any]]:
        """``(name, value)`` of every key; without the derived ones if ``derived`` is false."""
        for name in names(type(self)):
            if derived or name not in self.derived:
                yield name, getattr(self, name)


@dataclass(frozen=True)
class NoParams(Params):
    """The parameters of a model that has none."""


def file_path(key: str, value: Any, allowed: str, names: tuple[str, ...] = ()) -> str:
    """A file's path made absolute (a run directory's config.toml then finds it from
    anywhere); "" (none) and the ``names`` of shipped examples as given; a blank or
    non-printable value refused, ``allowed`` saying what is."""
    value = coerce_value(key, value, str)
    if value == "" or value in names:
        return value
    if not value.strip() or not value.isprintable():
        raise ConfigError(key, value, allowed)
    return str(Path(value).expanduser().absolute())


def each_once(key: str, names: tuple[str, ...], why: str) -> tuple[str, ...]:
    """``names`` (a list of a key), refused if one is given twice (``why`` says why not)."""
    twice = next((n for k, n in enumerate(names) if n in names[:k]), None)
    if twice is not None:
        raise ConfigError(key, list(names), f"names {twice!r} twice: {why}")
    return names


def _keys(cls: type) -> list[dataclasses.Field]:
    # A nested field holds another Params (a sub-model's), whose keys are its own.
    return [f for f in dataclasses.fields(cls) if f.init and not f.metadata.get("nested")]


def names(cls: type) -> list[str]:
    """The configuration keys of a Params class, in order."""
    return [f.name for f in _keys(cls)]


def describe(cls: type) -> list[tuple[str, Any, str, str]]:
    """``(name, default, meaning, rule)`` of every key of a Params class; ``rule`` says how a
    default derived from other keys is derived ("" for the others)."""
    out = []
    for f in _keys(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = None
        out.append((f.name, default, f.metadata.get("doc", ""), f.metadata.get("rule", "")))
    return out


def plain(value: Any) -> Any:
    """A value as TOML writes it: a choice as its name, a tuple as a list."""
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, tuple):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value


# The most events one key may schedule in a run: beyond, the schedule alone outlasts any
# session (a period or a rate mistyped by orders of magnitude).
MAX_EVENTS_PER_RUN = 100_000_000


def check_schedules(params: Params, duration_s: float, n_robots: int) -> None:
    """Refuse a key marked ``schedules`` (:func:`param`) that would schedule more than
    :data:`MAX_EVENTS_PER_RUN` events in a run of ``duration_s`` of ``n_robots`` robots."""
    for f in _keys(type(params)):
        who = f.metadata.get("schedules", "")
        value = getattr(params, f.name)
        if not who or value is None:
            continue
        per_s = value if f.name.endswith("_hz") else 1.0 / value
        # A team too large for a float counts as 10^300: refused alike, not an overflow.
        robots = who == "robot"
        count = duration_s * per_s * (float(min(n_robots, 10**300)) if robots else 1.0)
        refuse_events(
            f"{params.section}.{f.name}",
            value,
            count,
            duration_s,
            f"{n_robots} robots each" if robots else "the run",
            "duration_s or world.n_robots" if robots else "duration_s",
        )


def refuse_events(key: str, value: Any, count: float, duration_s: float, each: str, others: str) -> None:
    """Refuse ``key`` (a period, or a rate named ``_hz``) if ``each`` (``"the run"``, or the
    robots) would make more than :data:`MAX_EVENTS_PER_RUN` events of it in ``duration_s``;
    the message says to change it or lower ``others``."""
    if count > MAX_EVENTS_PER_RUN:
        change = "lower" if key.endswith("_hz") else "raise"
        raise ConfigError(
            key,
            value,
            f"{each} would make {count:.3g} events of it in duration_s = {duration_s:g} s, more than "
            f"{MAX_EVENTS_PER_RUN:,}; {change} it, or lower {others}",
        )
