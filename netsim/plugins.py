"""Models found by name: the paper's "reserved interfaces" for users' own algorithms.

A model (a mobility model, a protocol, a controller) is a *plugin*: an object that
declares its parameters (a :class:`~netsim.params.Params` dataclass: its own keys of its
configuration section, validated when made), the output tables it writes (with their
columns), the rules that tie its keys to other sections (:meth:`Plugin.check`), and how it
is built from its parameters and the parts of the run it works with (:class:`Parts`).
:class:`PluginSpec` spells one out. A built component that adds figures to a run's summary
implements :class:`Reports`.

Built-in plugins are entry points in ``pyproject.toml`` (groups ``netsim.mobility``,
``netsim.protocols``, ``netsim.controllers``, ``netsim.hooks``, and the channel's models
``netsim.propagation``, ``netsim.loss``, ``netsim.mac``), each naming a plugin object
(``netsim.mobility.random_waypoint:PLUGIN``); a user's own is named ``"package.module:attr"`` in
the configuration. So the engine never imports the packages that build on it, and names
none of their models. A plugin is a :class:`PluginSpec` or an object with its members, and
nothing else: a component is handed its parameters and collaborators when it is built,
never the whole simulation (docs/plugins.md, "One form of plugin").
"""

from __future__ import annotations

import importlib
import os
import sys
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, is_dataclass
from functools import cache
from importlib.metadata import entry_points
from types import ModuleType
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, runtime_checkable

import simpy

from netsim.errors import ConfigError
from netsim.params import Params
from netsim.radio.models import CHANNEL_GROUPS, wants_members

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd

    from netsim.control import ControlLoop
    from netsim.events import EventBus
    from netsim.groups import GroupView
    from netsim.radio.channel import Channel
    from netsim.rng import Streams
    from netsim.state import RobotState
    from netsim.trace import Trace

MOBILITY = "netsim.mobility"
PROTOCOLS = "netsim.protocols"
CONTROLLERS = "netsim.controllers"
HOOKS = "netsim.hooks"

# A table's columns and their dtypes (numpy names; "object" for strings).
Schema = Mapping[str, str]


class RoleLabels(NamedTuple):
    """How a protocol's roles are written in ``roles.parquet``: the role labels, and the
    cause recorded when a member loses its leader by timeout. Tools that read finished
    runs get them from the run's protocol plugin, never from literals."""

    leader: str
    member: str
    undecided: str
    leader_lost: str


class AckTiming(NamedTuple):
    """When a robot's Acks come, for controllers that plan on their absence (the local
    plan's release, docs/model.md 5.1): the protocol's ``ack_period_s`` and ``ack_jitter_s``
    (each robot sends an Ack at most ``period_s + jitter_s`` after its previous one), and
    whether the channel delivers every frame to every robot its radio lets hear it
    (``lossless``: the Bernoulli loss model at ``loss_probability = 0`` and no shared
    medium), so that a missed Ack means the link was down when it was sent."""

    period_s: float
    jitter_s: float
    lossless: bool


@dataclass(frozen=True)
class Parts:
    """What a model is built with: the run's core, the world, the run's event bus
    (``events``: subscribe to what happens, as it happens), and for controllers and hooks
    the control loop and the protocol's view of the groups (None without groups)."""

    env: simpy.Environment
    state: RobotState
    channel: Channel
    trace: Trace
    streams: Streams
    world: Any  # netsim.config.WorldParams
    duration_s: float
    output: Any  # netsim.config.OutputParams
    control: ControlLoop | None = None
    groups: GroupView | None = None
    events: EventBus | None = None
    # The world's occupancy map (netsim.world.maps.OccupancyMap), None in open space.
    occupancy: Any = None
    # For protocols, controllers and hooks: the links as the channel makes them (the same as
    # links.parquet), solved during the run. Call it while building (it starts the runtime
    # link solver); None when the run solves no link events during the run.
    links: Callable[[], LinkState] | None = None
    # The flows of traffic.flows and the largest payload of one frame
    # (netsim.traffic.Traffic), for the protocol that carries them; None: no flows.
    traffic: Any = None
    # channel.max_frame_bytes: the largest payload of one frame (a protocol that packs
    # several messages into a frame keeps under it).
    max_frame_bytes: int = 1500
    # For controllers: the Ack beacon's timing and whether the channel loses frames; None
    # when the protocol sends no Acks.
    acks: AckTiming | None = None


class LinkState(Protocol):
    """The links up now, as the channel makes them under the run's radio (a runtime link
    solver: :class:`~netsim.links.kinetic.RuntimeLinks` and its kin)."""

    def up_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """Arrays ``(a, b)``, ``a < b``: the links up now."""
        ...

    @property
    def now_s(self) -> float:
        """The instant they are up at: the run's present."""
        ...


class Plugin(Protocol):
    """A model: its own parameters, its tables, its rules across sections, how it is built."""

    Params: type[Params]  # a frozen dataclass: the model's own keys of its section
    tables: Mapping[str, Schema]  # output tables it writes, with their columns

    def check(self, params: Any, config: Any) -> None:
        """Rules between the model's keys and other sections of ``config`` (ConfigError)."""
        ...

    def build(self, params: Any, parts: Parts) -> object:
        """The model's component for one run, its processes started."""
        ...


@runtime_checkable
class Reports(Protocol):
    """A built component that adds its own figures to the run's summary."""

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict: ...


def _no_check(params: Any, config: Any) -> None:
    return None


@dataclass(frozen=True)
class PluginSpec:
    """A plugin spelled out (see :class:`Plugin`); the flags say what other models and the
    engine may rely on."""

    Params: type[Params]
    build: Callable[[Any, Parts], object]
    tables: Mapping[str, Schema] = field(default_factory=dict)
    check: Callable[[Any, Any], None] = _no_check
    # The model used when the configuration names none of its group.
    default: bool = False
    # Mobility: whether the model moves the robots (False: controllers may move them), and
    # whether it keeps them in the free cells of a map (world.map): one that moves robots
    # and does not is refused on a map.
    moves_robots: bool = True
    respects_map: bool = False
    # Protocols: whether the component forms groups (is a GroupView), and how its roles
    # are written in roles.parquet.
    forms_groups: bool = False
    role_labels: RoleLabels | None = None
    # Protocols: whether the component relays the flows of ``traffic.flows`` (Parts.traffic).
    carries_flows: bool = False
    # Controllers with a section: ``timing(params) -> (period_s, start_s)`` of the control
    # loop, if the section sets it.
    timing: Callable[[Any], tuple[float, float]] | None = None


def _import_user_module(name: str) -> ModuleType:
    """Import ``name``; a module in the current directory counts, as with ``python -m``
    (a console script's import path does not include it)."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name.split(".")[0] or os.getcwd() in sys.path:
            raise
        sys.path.insert(0, os.getcwd())
        return importlib.import_module(name)


@cache
def _entry_points(group: str) -> tuple:
    # Read once per process: entry points do not change while it runs.
    return tuple(_every_entry_point().select(group=group))


@cache
def _every_entry_point() -> Any:
    # One reading of every installed distribution's entry points serves all the groups
    # (a reading per group costs as much as one for all).
    return entry_points()


def available(group: str) -> list[str]:
    """Names of the registered plugins of ``group``."""
    return sorted(ep.name for ep in _entry_points(group))


_MEMBERS = ("Params", "tables", "check", "build")


@cache
def _plugin(group: str, name: str) -> Any:
    """The plugin ``name`` of ``group`` as a PluginSpec (an object with the members of
    :class:`Plugin` is wrapped in one); a channel model (:mod:`netsim.radio.models`) as it
    is, once it has its kind's members."""
    obj = _load(group, name)
    if group in CHANNEL_GROUPS:
        wanted = wants_members(group)
        kind = CHANNEL_GROUPS[group]
        if not all(hasattr(obj, m) for m in wanted):
            raise TypeError(f"is not a {kind.__name__} (an object with " + ", ".join(wanted) + ")")
        for other_group, other in CHANNEL_GROUPS.items():
            # Another kind's members can match (a loss model has Params and make too); its
            # calls would not, midway through the build.
            if other_group != group and isinstance(obj, other) and not isinstance(obj, kind):
                raise TypeError(f"is a {other.__name__} (of {other_group}), not a {kind.__name__} (of {group})")
        if not isinstance(obj, kind):
            # An object with the members: the kind's defaults for those it lacks (tables, check).
            obj = kind(**{f.name: getattr(obj, f.name) for f in fields(kind) if hasattr(obj, f.name)})
        if getattr(obj, "build", None) is not None and getattr(obj, "airtime_s", False) is None:
            # The protocols' checks read a frame's airtime from a medium; None means none.
            raise TypeError("is a medium (it has a build) without airtime_s(params, nbytes)")
        return obj
    if isinstance(obj, PluginSpec):
        return _checked_params(obj)
    if all(hasattr(obj, m) for m in _MEMBERS):
        # Every member a PluginSpec has, the flags too (moves_robots, respects_map, ...).
        given = {f.name: getattr(obj, f.name) for f in fields(PluginSpec) if hasattr(obj, f.name)}
        return _checked_params(PluginSpec(**given))
    raise TypeError("is not a netsim plugin (a PluginSpec, or an object with " + ", ".join(_MEMBERS) + ")")


def _checked_params(spec: PluginSpec) -> PluginSpec:
    """``spec``, once its ``Params`` is what the configuration reads keys into."""
    p = spec.Params
    frozen = getattr(getattr(p, "__dataclass_params__", None), "frozen", False)
    if not (isinstance(p, type) and issubclass(p, Params) and is_dataclass(p) and frozen):
        raise TypeError(
            f"its Params ({getattr(p, '__name__', repr(p))}) must be a frozen dataclass deriving from "
            "netsim.params.Params (NoParams for none)"
        )
    return spec


class PluginImportError(ImportError):
    """A plugin's module failed while it was imported (a syntax error, an exception raised by
    its code): told in one line, the file and line where it failed, the error's kind and
    message, as the traceback's last lines would."""


def _where(exc: BaseException) -> str:
    """``FILE, line N`` of the failure: for a syntax error, where the parser stopped; else
    the innermost frame of the traceback that is the user's code (not Python's import
    machinery nor an installed library), the innermost frame if there is none."""
    if isinstance(exc, SyntaxError) and exc.filename:
        return f"{exc.filename}, line {exc.lineno}"
    frames = traceback.extract_tb(exc.__traceback__)
    libraries = {os.path.realpath(p) for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
    own = [
        f
        for f in frames
        if not f.filename.startswith("<") and not any(os.path.realpath(f.filename).startswith(p) for p in libraries)
    ]
    candidates = own or [f for f in frames if not f.filename.startswith("<")] or list(frames)
    if not candidates:
        return "?"
    return f"{candidates[-1].filename}, line {candidates[-1].lineno}"


def _import_failure(exc: BaseException) -> PluginImportError:
    message = exc.msg if isinstance(exc, SyntaxError) else str(exc)
    text = f"{_where(exc)}: {type(exc).__name__}" + (f": {message}" if message else "")
    return PluginImportError(" ".join(text.split()))  # one line, whatever the message holds


def _names_the_plugin(exc: ModuleNotFoundError, name: str) -> bool:
    """Whether the module not found is the plugin's own (or a package on its path)."""
    module_name = name.partition(":")[0]
    return bool(exc.name) and (module_name == exc.name or module_name.startswith(f"{exc.name}."))


def _load(group: str, name: str) -> Any:
    try:
        if ":" in name:
            module_name, _, attr = name.partition(":")
            obj = _import_user_module(module_name)
        else:
            found = [ep for ep in _entry_points(group) if ep.name == name]
            if not found:
                raise LookupError(name)
            return found[0].load()
    except LookupError:
        raise
    except ImportError as exc:
        if isinstance(exc, ModuleNotFoundError) and _names_the_plugin(exc, name):
            raise  # no such module: nothing ran, no file to name
        raise _import_failure(exc) from exc
    except Exception as exc:  # the module's own code failed as it ran: its file and line
        raise _import_failure(exc) from exc
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def resolve(group: str, name: str, key: str) -> Any:
    """The plugin ``name`` of ``group``; ``key`` is the configuration key, for errors."""
    if not isinstance(name, str) or not name:
        raise ConfigError(key, name, "must be the name of a plugin (a non-empty string)")
    if ":" in name and not all(name.partition(":")[::2]):
        raise ConfigError(key, name, "must be 'package.module:attr', both parts given")
    try:
        return _plugin(group, name)
    except LookupError:
        choices = ", ".join(repr(n) for n in available(group)) or "none installed"
        raise ConfigError(key, name, f"unknown; choose one of {choices}, or 'package.module:attr'") from None
    except TypeError as exc:
        raise ConfigError(key, name, str(exc)) from None
    except (ImportError, AttributeError, ValueError) as exc:
        raise ConfigError(key, name, f"cannot be loaded ({exc})") from None


def registered(group: str) -> dict[str, Any]:
    """Every registered plugin of ``group`` that loads, by name."""
    return dict(_registered(group))


@cache
def _registered(group: str) -> dict[str, Any]:
    out = {}
    for name in available(group):
        try:
            out[name] = resolve(group, name, group)
        except ConfigError:
            continue  # a broken third-party plugin must not stop runs that do not use it
    return out


def default_name(group: str) -> str:
    """The registered plugin of ``group`` that declares itself the default."""
    names = [name for name, p in registered(group).items() if p.default]
    if len(names) != 1:
        raise ConfigError(group, names, "exactly one registered plugin must declare itself the default")
    return names[0]
