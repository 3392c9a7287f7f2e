"""The channel's models as plugins: what a propagation model, a loss model and a MAC declare.

Each kind is an entry-point group, as the mobility models are: ``netsim.propagation``
(``unit_disk``, ``log_distance``), ``netsim.loss`` (``bernoulli``, ``distance``,
``gilbert_elliott``) and ``netsim.mac`` (``none``, ``aloha``, ``csma``). The keys
``channel.propagation``, ``channel.loss_model`` and ``channel.mac`` name one of each, by
entry-point name or as ``"package.module:attr"``. A model's own keys are keys of
``[channel]``: its :class:`~netsim.params.Params` declares them (``section = "channel"``),
with their checks and meanings, and ``netsim config`` lists them.

The engine asks a model what it needs through the members below and never compares a
model's name: a user's model with the same members runs as a built-in one does.
docs/plugins.md shows how to write each kind.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from netsim.params import Params

PROPAGATION = "netsim.propagation"
LOSS = "netsim.loss"
MAC = "netsim.mac"


def _no_check(params: Any, channel: Any) -> None:
    return None


def _nothing(params: Any) -> None:
    return None


def _never(params: Any) -> bool:
    return False


def _no_power(params: Any, noise_floor_dbm: float, capture_threshold_db: float) -> None:
    return None


@dataclass(frozen=True)
class PropagationModel:
    """A propagation model: who can hear a frame.

    ``make(params, range_m, occupancy, rng)`` returns the reception decision, a
    :class:`~netsim.radio.propagation.Propagation` (a chain of loss terms with a power
    budget), or None for the plain unit disk of ``channel.range_m``, which the channel
    decides by distance alone. ``range_m`` is every robot's range, ``occupancy`` the
    world's map (None in open space), ``rng`` the channel's stream ``channel.shadowing``.

    ``ranges(params)``: the range every robot has under the model (where a pair is linked
    without shadowing or walls), or None when ``channel.range_m`` sets it. Link events
    are solved as crossings of that range, so a model that returns one must decide links
    by distance within it (in open space, without random terms).
    ``reach(params)``: the distance beyond which no pair ever links (None: the range).
    ``shadowed(params)``: whether links are random (the links table then records the
    channel's decisions instead of solving them).
    ``power(params, noise_floor_dbm, capture_threshold_db)``: the mean received power a
    shared medium sums for interference (:class:`netsim.radio.mac.PowerModel`), None when
    the model has no notion of power (a frame is then lost when another overlaps it).
    ``check(params, channel)``: rules between the model's keys and the rest of
    ``[channel]`` (:class:`~netsim.errors.ConfigError`).
    """

    Params: type[Params]
    make: Callable[[Any, np.ndarray, Any, np.random.Generator], Any]
    ranges: Callable[[Any], float | None] = _nothing
    reach: Callable[[Any], float | None] = _nothing
    shadowed: Callable[[Any], bool] = _never
    power: Callable[[Any, float, float], Any] = _no_power
    check: Callable[[Any, Any], None] = _no_check
    default: bool = False


@dataclass(frozen=True)
class LossModel:
    """A reception loss model: ``make(params, range_m, rng)`` returns the callable
    ``survives(sender, receivers, distances_m) -> mask or None`` (:mod:`netsim.radio.loss`),
    drawing from ``rng``: for a plugin the channel's stream ``channel.loss``, a numpy
    generator; for the built-in models a :class:`~netsim.rng.KindStreams`, a stream per kind
    of frame (``channel.loss.<kind>``). ``lossless(params)``:
    whether under these keys it never drops a frame (then a frame the radio lets through
    arrives, unless a medium loses it); by default it may."""

    Params: type[Params]
    make: Callable[[Any, np.ndarray, np.random.Generator], Any]
    check: Callable[[Any, Any], None] = _no_check
    lossless: Callable[[Any], bool] = _never
    default: bool = False


@dataclass(frozen=True)
class MacModel:
    """A medium access control: how frames share the air.

    ``build(params, channel, rng, power)``: the medium attached to the channel, through
    which every frame then goes (:class:`netsim.radio.mac.Medium` is the example: it
    implements ``send``, ``causes``, ``summary`` and ``frame``); ``rng`` is the stream
    ``channel.mac``; ``power(noise_floor_dbm, capture_threshold_db)`` gives the
    propagation model's mean received power (:attr:`PropagationModel.power`; None
    without one). None: no medium, the channel of infinite capacity.
    ``airtime_s(params, nbytes)``: how long a frame of ``nbytes`` occupies the air, for
    the protocols' checks (None without a medium).
    ``tables(tables)``: the run's tables with the medium's own (its drop causes in the
    protocols' tables, and a table of its own).
    ``check(params, channel)``: rules between its keys and the rest of ``[channel]``.
    """

    Params: type[Params]
    build: Callable[[Any, Any, np.random.Generator, Any], Any] | None = None
    airtime_s: Callable[[Any, int], float] | None = None
    tables: Callable[[dict], dict] = field(default=lambda tables: tables)
    check: Callable[[Any, Any], None] = _no_check
    default: bool = False


def wants_members(group: str) -> tuple[str, ...]:
    """The members a plugin of ``group`` must have."""
    return {PROPAGATION: ("Params", "make"), LOSS: ("Params", "make"), MAC: ("Params", "build", "airtime_s")}[group]


@dataclass(frozen=True)
class NoMacParams(Params):
    """Without a medium (``channel.mac = "none"``) there are no keys."""

    section = "channel"


NO_MAC = MacModel(NoMacParams, default=True)
"""``channel.mac = "none"``: no medium; every transmission is decided when it is sent."""

CHANNEL_GROUPS: Mapping[str, type] = {PROPAGATION: PropagationModel, LOSS: LossModel, MAC: MacModel}
