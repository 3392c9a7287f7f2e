"""Run configuration: TOML files, ``--set`` overrides, validation.

A configuration is a tree of small frozen dataclasses (:mod:`netsim.params`), one per
section. The engine owns ``seed``, ``duration_s`` and the sections ``[world]``,
``[channel]``, ``[control]``, ``[events]`` and ``[output]``; each model owns its keys: ``[mobility]`` is
``model`` and the chosen mobility model's own keys, ``[protocol]`` likewise, the channel's
``loss_model`` picks a loss model whose keys join ``[channel]``, and a controller may own a
section of its own (the coverage controller's ``[coverage]``, or a user's). Every value is
checked when the configuration is made, however it is made; a bad one raises
:class:`~netsim.errors.ConfigError` naming the key, the value and what is allowed. A key
that no model knows is an error, so a typo never passes silently; a key of another model
of the same section (``mobility.trace_file`` with random waypoint) is accepted and ignored
with a one-line warning (:class:`ConfigWarning`), and the resolved configuration holds only
the keys that apply.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from netsim import plugins
from netsim.area import KEY, MAX_COORDINATE_M, Bounds, OnTorus, area_side, parse_bounds, parse_start
from netsim.errors import ConfigError, NetsimInputError, did_you_mean, not_a_file
from netsim.params import (
    NoParams,
    Params,
    check_schedules,
    coerce_value,
    each_once,
    file_path,
    finite,
    frame_size,
    names,
    non_negative,
    param,
    plain,
    positive,
)
from netsim.params import (
    describe as describe_params,
)
from netsim.radio.models import LOSS, MAC, PROPAGATION
from netsim.traffic import TrafficParams, check_flows

# The shortest range a run takes: below, a link's events come closer together than the
# solver's least window (a range mistyped by orders of magnitude).
MIN_RANGE_M = 0.01


class ConfigWarning(UserWarning):
    """A key that is accepted but not used (it belongs to another model)."""


# -- the engine's sections -------------------------------------------------------------------
def _map_path(key: str, value: Any) -> str:
    """A map's YAML path made absolute; an example's name and "" (no map) as given."""
    from netsim.world.maps import EXAMPLES

    return file_path(key, value, 'must be the path of a map_server YAML file, "office", "cave", or ""', EXAMPLES)


def _placement(key: str, value: Any) -> str:
    """A placement's name as given; a CSV file that exists made absolute, as a map's path is
    (a run's config.toml, a learning environment's next episode, find it from anywhere).
    Anything else stays as given, for the placement's own check to name."""
    value = coerce_value(key, value, str)
    if value in NAMED_PLACEMENTS or not Path(value).expanduser().is_file():
        return value
    return file_path(key, value, "")


# The placements named by a word (netsim.placement.PLACEMENTS, and "connected"); any other
# value of world.placement is the path of a CSV file.
NAMED_PLACEMENTS = ("uniform", "grid", "centre", "connected")


@dataclass(frozen=True)
class WorldParams(Params, OnTorus):
    section = "world"
    n_robots: int = param(50, positive, "number of robots N")
    side_m: float = param(1000.0, area_side, f"side of the square area A, metres, at most {MAX_COORDINATE_M:g}")
    bounds_m: tuple[float, float, float, float] | str = param(
        None,
        None,
        'the area [x_min, y_min, x_max, y_max] in the world (the map\'s) frame, metres, or "map" for the whole '
        "extent of world.map",
        coerce=parse_bounds,
        derive=lambda p: (0.0, 0.0, p.side_m, p.side_m),
        rule="[0, 0, side_m, side_m]",
    )
    placement: str = param(
        "uniform",
        None,
        '"uniform", "grid", "centre", "connected" (a start whose links at t = 0 form one network), '
        "or a path to a CSV file with columns x_m,y_m (made absolute, as a map's)",
        coerce=_placement,
    )
    centre_side_m: float = param(
        250.0,
        positive,
        'placement = "centre": side of the central square; "connected": of the square about start_m, metres',
    )
    start_m: tuple[float, float] | str = param(
        "centre",
        None,
        'placement = "connected": the start point [x, y] in the world frame, metres (on a map, in a free cell: '
        'robots start in its free region), or "centre" for the area\'s centre',
        coerce=parse_start,
    )
    torus: bool = param(False, None, "wrap the area's borders (distances taken on a torus)")
    map: str = param(
        "",
        None,
        'occupancy map: a ROS map_server YAML file, or "office" / "cave" (shipped examples); "" for open space',
        coerce=_map_path,
    )

    def check(self) -> None:
        bounds = self.bounds_m
        if bounds == "map" and not self.map:
            raise ConfigError(KEY, "map", "needs a map (world.map)")
        if self.torus and bounds != (0.0, 0.0, self.side_m, self.side_m):
            raise ConfigError(
                KEY, plain(bounds), "cannot be set with world.torus = true (the torus is the square [0, side_m]^2)"
            )
        if self.placement == "centre" and bounds != "map":
            self.check_centre(Bounds(*bounds))
        if self.start_m != "centre" and bounds != "map" and not Bounds(*bounds).contains([self.start_m])[0]:
            raise ConfigError("world.start_m", list(self.start_m), f"is outside the area {list(bounds)}")

    def check_centre(self, area: Bounds) -> None:
        """``placement = "centre"``: the central square fits in the area."""
        if self.centre_side_m <= min(area.width, area.height):
            return
        if area.is_square_at_origin and area.width == self.side_m:
            raise ConfigError(
                "world.centre_side_m", self.centre_side_m, f"must not exceed world.side_m = {self.side_m}"
            )
        raise ConfigError(
            "world.centre_side_m",
            self.centre_side_m,
            f"must not exceed the area's shorter side ({min(area.width, area.height):g} m, world.bounds_m)",
        )


def _ranges(key: str, value: Any) -> float | tuple[float, ...]:
    if isinstance(value, list | tuple):
        out = tuple(coerce_value(f"{key}[{i}]", v, float) for i, v in enumerate(value))
        for i, v in enumerate(out):
            if not (v > 0 and math.isfinite(v)):
                raise ConfigError(f"{key}[{i}]", v, "must be a finite number > 0 (metres)")
        return out
    r = coerce_value(key, value, float)
    if not (r > 0 and math.isfinite(r)):
        raise ConfigError(key, r, "must be a finite number > 0 (metres)")
    return r


def _model_name(group: str, what: str) -> Callable[[str, Any], str]:
    """A coercion: the name of a channel model of ``group`` (entry point or
    ``"package.module:attr"``), refused at once when no such model loads."""

    def coerce(key: str, value: Any) -> str:
        if not isinstance(value, str):
            raise ConfigError(key, value, f"must be the name of a {what} (a string)")
        plugins.resolve(group, value, key)
        return value

    return coerce


# The channel's models: the key that names each, its entry-point group, and the attribute
# of ChannelParams that holds its parameters.
CHANNEL_MODELS = (("propagation", PROPAGATION, "radio"), ("loss_model", LOSS, "loss"), ("mac", MAC, "medium"))


@dataclass(frozen=True)
class ChannelParams(Params):
    """The channel's own keys, and the parameters of the models its keys name:
    ``radio`` (``propagation``), ``loss`` (``loss_model``) and ``medium`` (``mac``), whose
    keys are keys of ``[channel]`` too (read through: ``channel.loss_probability``)."""

    section = "channel"
    range_m: float | tuple[float, ...] = param(
        150.0, None, "communication range r_c in metres, or a list of one range per robot", coerce=_ranges
    )
    latency_s: float = param(0.001, finite(non_negative), "fixed delay of every transmission, s")
    latency_jitter_s: float = param(0.0, finite(non_negative), "extra delay uniform on [0, jitter], s")
    loss_model: str = param(
        "bernoulli",
        None,
        "loss model: a plugin of netsim.loss (bernoulli, distance, gilbert_elliott) or 'package.module:attr'",
        coerce=_model_name(LOSS, "loss model"),
    )
    propagation: str = param(
        "unit_disk",
        None,
        "propagation model: a plugin of netsim.propagation (unit_disk, log_distance) or 'package.module:attr'",
        coerce=_model_name(PROPAGATION, "propagation model"),
    )
    # The shared medium (docs/radio.md); "none" is the channel of infinite capacity.
    mac: str = param(
        "none",
        None,
        "medium access: 'none' (infinite capacity), 'aloha', 'csma', or 'package.module:attr'",
        coerce=_model_name(MAC, "medium access control"),
    )
    max_frame_bytes: int = param(
        1500, frame_size, "largest payload of one frame, bytes: a flow's larger packets travel as several frames"
    )
    loss: Params = field(default=None, metadata={"nested": True})  # type: ignore[assignment]
    radio: Params = field(default=None, metadata={"nested": True})  # type: ignore[assignment]
    medium: Params = field(default=None, metadata={"nested": True})  # type: ignore[assignment]

    def __post_init__(self) -> None:
        super().__post_init__()
        for key, _, attr in CHANNEL_MODELS:
            wanted = self.model(key).Params
            value = getattr(self, attr)
            if value is None:
                object.__setattr__(self, attr, wanted())
            elif type(value) is not wanted:
                raise ConfigError(
                    f"channel.{key}",
                    getattr(self, key),
                    f"has parameters {wanted.__name__}, not {type(value).__name__}",
                )
        for key, _, attr in CHANNEL_MODELS:
            self.model(key).check(getattr(self, attr), self)

    def model(self, key: str) -> Any:
        """The model that ``key`` (``propagation``, ``loss_model``, ``mac``) names."""
        group = next(g for k, g, _ in CHANNEL_MODELS if k == key)
        return plugins.resolve(group, getattr(self, key), f"channel.{key}")

    @property
    def propagation_model(self) -> Any:
        """The propagation model (:class:`~netsim.radio.models.PropagationModel`)."""
        return self.model("propagation")

    @property
    def loss_plugin(self) -> Any:
        """The loss model (:class:`~netsim.radio.models.LossModel`)."""
        return self.model("loss_model")

    @property
    def mac_model(self) -> Any:
        """The medium access control (:class:`~netsim.radio.models.MacModel`)."""
        return self.model("mac")

    def airtime_s(self, nbytes: int) -> float | None:
        """How long a frame of ``nbytes`` occupies the air under the medium; None without one."""
        mac = self.mac_model
        return None if mac.airtime_s is None else float(mac.airtime_s(self.medium, nbytes))

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        for _, _, sub in CHANNEL_MODELS:
            params = self.__dict__.get(sub)
            if params is not None and name in names(type(params)):
                return getattr(params, name)
        raise AttributeError(name)


def _controllers(key: str, value: Any) -> tuple[str, ...]:
    if not isinstance(value, list | tuple):
        raise ConfigError(key, value, "must be a list of plugin names")
    given = tuple(coerce_value(f"{key}[{i}]", v, str) for i, v in enumerate(value))
    # Built twice, the second would take the first's tables and summary keys unsaid.
    return each_once(key, given, "each plugin runs once")


def _options(key: str, value: Any) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(key, value, "must be a table ([control.options])")
    return dict(value)


@dataclass(frozen=True)
class ControlParams(Params):
    section = "control"
    controllers: tuple[str, ...] = param(
        (), None, "user controllers and hooks, by plugin name or 'package.module:attr'", coerce=_controllers
    )
    options: dict = param(
        None, None, "free table of options for user controllers", coerce=_options, default_factory=dict
    )


def _runtime_links(key: str, value: Any) -> str:
    if value not in RUNTIME_LINKS:
        raise ConfigError(key, value, "must be one of " + ", ".join(repr(v) for v in RUNTIME_LINKS))
    return value


RUNTIME_LINKS = ("auto", "on", "off")


@dataclass(frozen=True)
class EventsParams(Params):
    """What happens during the run, announced as it happens (docs/events.md)."""

    section = "events"
    hooks: tuple[str, ...] = param(
        (), None, "logging and analysis hooks, by plugin name or 'package.module:attr'", coerce=_controllers
    )
    runtime_links: str = param(
        "auto",
        None,
        "'auto': link events solved during the run when something subscribes to link_up or link_down"
        " (else after it); 'on': always; 'off': never (subscribing to them is then an error)",
        coerce=_runtime_links,
    )
    live_topology: bool = param(
        False, None, "keep a networkx graph of the links current during the run; adds its time-averaged levels"
    )


@dataclass(frozen=True)
class OutputParams(Params):
    section = "output"
    position_interval_s: float = param(
        1.0,
        finite(non_negative),
        "sampling interval of positions.parquet (0: none) and of the protocol's samples "
        "(groups, beliefs, neighbour_beliefs, ack_delivery; 0: every ack_period_s), s",
    )
    receptions: bool = param(
        False,
        None,
        "write receptions.parquet: one row per robot within the radio's reach of each frame, with its "
        "distance, received power, SINR, and whether it was received or why not (docs/outputs.md)",
    )


# -- sections that name a model ------------------------------------------------------------
@dataclass(frozen=True)
class ModelSection:
    """A section that names a model (``model``) and holds that model's own parameters
    (``params``); the parameters read through (``config.mobility.speed_max_mps``)."""

    group: ClassVar[str] = ""
    section: ClassVar[str] = ""
    model: str = ""  # "": the group's default model
    params: Params = None  # type: ignore[assignment]  # None: the model's defaults

    def __post_init__(self) -> None:
        key = f"{self.section}.model"
        model = self.model or plugins.default_name(self.group)
        if not isinstance(model, str):
            raise ConfigError(key, model, "must be a string")
        plugin = plugins.resolve(self.group, model, key)
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "_plugin", plugin)
        if self.params is None:
            object.__setattr__(self, "params", plugin.Params())
        elif type(self.params) is not plugin.Params:
            raise ConfigError(key, model, f"has parameters {plugin.Params.__name__}, not {type(self.params).__name__}")

    @property
    def plugin(self) -> Any:
        """The model's plugin."""
        return self.__dict__["_plugin"]

    def __getattr__(self, name: str) -> Any:
        params = self.__dict__.get("params")
        if params is None or name.startswith("_"):
            raise AttributeError(name)
        return getattr(params, name)


@dataclass(frozen=True)
class MobilitySection(ModelSection):
    group = plugins.MOBILITY
    section = "mobility"


@dataclass(frozen=True)
class ProtocolSection(ModelSection):
    group = plugins.PROTOCOLS
    section = "protocol"


def _nested(cls: type) -> Any:
    return field(default_factory=cls, metadata={"nested": True})


ENGINE_SECTIONS = ("world", "mobility", "channel", "protocol", "traffic", "control", "events", "output")


@dataclass(frozen=True)
class Config(Params):
    """A whole run's configuration. ``sections`` holds the sections that controllers own
    (``[coverage]``, or a user's), read as attributes (``config.coverage``)."""

    seed: int = param(1, non_negative, "seed of every random stream")
    duration_s: float = param(300.0, finite(positive), "simulated time, s")
    world: WorldParams = _nested(WorldParams)
    mobility: MobilitySection = _nested(MobilitySection)
    channel: ChannelParams = _nested(ChannelParams)
    protocol: ProtocolSection = _nested(ProtocolSection)
    traffic: TrafficParams = _nested(TrafficParams)
    control: ControlParams = _nested(ControlParams)
    events: EventsParams = _nested(EventsParams)
    output: OutputParams = _nested(OutputParams)
    sections: Mapping[str, Params] = field(default_factory=dict, metadata={"nested": True})

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not f.metadata.get("nested"):
                object.__setattr__(self, f.name, self._valid(f, value))
            elif f.name != "sections" and not isinstance(value, f.default_factory):  # type: ignore[arg-type]
                raise ConfigError(f.name, value, f"must be a {f.default_factory.__name__}")  # type: ignore[union-attr]
        object.__setattr__(self, "_derived", frozenset())
        object.__setattr__(self, "sections", _sections(self.control, dict(self.sections)))
        self.check()

    def __getattr__(self, name: str) -> Any:
        sections = self.__dict__.get("sections")
        if sections is None or name.startswith("_") or name not in sections:
            raise AttributeError(name)
        return sections[name]

    def check(self) -> None:
        """Rules across sections: the engine's, then each model's own (:meth:`Plugin.check`)."""
        ranges = self.channel.range_m
        if isinstance(ranges, tuple) and len(ranges) != self.world.n_robots:
            raise ConfigError(
                "channel.range_m",
                f"<list of {len(ranges)}>",
                f"a list must have one range per robot (world.n_robots = {self.world.n_robots})",
            )
        if self.world.torus and self.world.side_m <= 2 * max(self.ranges_m(), default=0.0):
            raise ConfigError("world.side_m", self.world.side_m, "on a torus must exceed twice the largest range_m")
        radio, propagation = self.channel.radio, self.channel.propagation_model
        r = self._range_m()
        least = min(r) if isinstance(r, tuple) else r
        if least < MIN_RANGE_M:
            implied = propagation.ranges(radio) is not None
            raise ConfigError(
                "channel.propagation" if implied else "channel.range_m",
                self.channel.propagation if implied else least,
                (f"the radio's implied range, {least:.3g} m, is" if implied else "is")
                + f" below {MIN_RANGE_M} m: no link lasts long enough for its events to be solved",
            )
        most = max(r) if isinstance(r, tuple) else r
        # A range past any area's size: its square, which the range tests form, heads for
        # overflow. A radio's implied range, and its reach under the strongest shadowing, are
        # as unbounded: a small exponent or a low sensitivity puts them anywhere.
        if propagation.ranges(radio) is None:
            if most > MAX_COORDINATE_M:
                raise ConfigError("channel.range_m", most, f"must be at most {MAX_COORDINATE_M:g} m")
        else:
            shadowed = propagation.shadowed(radio)
            # A model may leave its reach unsaid (None): its range then.
            reach = propagation.reach(radio) if shadowed else None
            shadowed = reach is not None
            farthest = max(reach, most) if reach is not None else most
            if not farthest <= MAX_COORDINATE_M:
                what = "reach under its strongest shadowing" if shadowed else "implied range"
                raise ConfigError(
                    "channel.propagation",
                    self.channel.propagation,
                    f"the radio's {what}, {farthest:.3g} m, is above {MAX_COORDINATE_M:g} m: raise "
                    f"path_loss_exponent or sensitivity_dbm, or lower tx_power_dbm{' or the shadowing' * shadowed}",
                )
        if self.world.torus and propagation.shadowed(radio):
            # The reach's disks around a robot's images must be disjoint, as the range's are:
            # the cut of a shadowed link where its pair leaves the reach is solved on one image.
            reach = propagation.reach(radio)
            if reach is not None and not self.world.side_m > 2 * reach:
                raise ConfigError(
                    "world.side_m",
                    self.world.side_m,
                    f"on a torus with shadowing must exceed twice the radio's reach ({reach:.1f} m)",
                )
        if self.world.map:
            _check_map(self)
        if self.traffic.flows:
            check_flows(self.traffic, self.world.n_robots, self.duration_s, self.channel.max_frame_bytes)
            if not getattr(self.protocol.plugin, "carries_flows", False):
                raise ConfigError(
                    "traffic.flows",
                    f"<list of {len(self.traffic.flows)}>",
                    f"protocol.model = {self.protocol.model!r} relays no messages: choose one that carries flows",
                )
        for plugin, params in self.models():
            plugin.check(params, self)
        for params in self._scheduling():
            check_schedules(params, self.duration_s, self.world.n_robots)
        for k, name in enumerate(self.events.hooks):
            hook = plugins.resolve(plugins.HOOKS, name, f"events.hooks[{k}]")
            if hook.Params.section:
                raise ConfigError(f"events.hooks[{k}]", name, "a hook cannot own a configuration section")
            hook.check(hook.Params(), self)
        if self.events.runtime_links == "off" and self.events.live_topology:
            raise ConfigError("events.live_topology", True, "needs link events during the run (events.runtime_links)")
        if self.channel.latency_s >= self.duration_s:
            raise ConfigError(
                "channel.latency_s",
                self.channel.latency_s,
                f"must be shorter than duration_s = {self.duration_s:g} s (no frame would arrive within the run)",
            )

    def _scheduling(self) -> list[Params]:
        """The sections of the models the run builds, whose keys may schedule events: the
        mobility model's, the protocol's, the controllers' and, with any controller, the
        section that sets the control loop's period."""
        out = [self.mobility.params, self.protocol.params]
        chosen = controllers(self)
        out += [params for _, _, params in chosen]
        if chosen:
            owners = section_owners(self.control)
            out += [self.sections[name] for name, plugin in owners.items() if plugin.timing is not None]
        return out

    def models(self) -> list[tuple[Any, Params]]:
        """``(plugin, params)`` of every model of the run with a section: the mobility model,
        the protocol, and the controllers that own a section."""
        out = [(self.mobility.plugin, self.mobility.params), (self.protocol.plugin, self.protocol.params)]
        owners = section_owners(self.control)
        out += [(owners[name], params) for name, params in self.sections.items()]
        return out

    def replace(self, **changes: Any) -> Config:
        """A copy with whole sections or top-level values replaced (as dicts or objects), and
        validated again; defaults derived from other keys (``tau_s``) are derived again
        unless given. A section whose ``model`` changes starts from that model's defaults."""
        tree = to_dict(self, derived=False)
        for key, value in changes.items():
            value = _as_tree(value)
            if isinstance(value, dict) and isinstance(getattr(self, key, None), ModelSection):
                if value.get("model", tree[key]["model"]) != tree[key]["model"]:
                    tree[key] = {}
            tree[key] = (
                merge(tree[key], value) if isinstance(value, dict) and isinstance(tree.get(key), dict) else value
            )
        return from_dict(tree)

    def radio_decides_links(self) -> bool:
        """Whether the channel's links are decided by more than the robots' ranges: walls (a
        map) or shadowing, so that only the run's own decisions give them."""
        channel = self.channel
        return bool(self.world.map) or bool(channel.propagation_model.shadowed(channel.radio))

    def ranges_m(self) -> tuple[float, ...]:
        """Per-robot ranges as a tuple of floats, one per robot."""
        r = self._range_m()
        return r if isinstance(r, tuple) else (r,) * self.world.n_robots

    def _range_m(self) -> float | tuple[float, ...]:
        """Every robot's range (a radio's implied range, or ``channel.range_m``), or each
        robot's (a tuple)."""
        implied = self.channel.propagation_model.ranges(self.channel.radio)
        if implied is not None:
            return float(implied)
        r = self.channel.range_m
        return r if isinstance(r, tuple) else float(r)


def world_bounds(world: Any) -> Bounds:
    """The area of a world (``netsim.config.WorldParams``): ``world.bounds_m``, ``"map"``
    being the whole extent of ``world.map``."""
    b = world.bounds_m
    if b == "map":
        from netsim.world.maps import cached_map

        x0, x1, y0, y1 = cached_map(world.map).extent_m
        return Bounds(x0, y0, x1, y1)
    return Bounds(*(float(v) for v in b))


def _check_map(config: Config) -> None:
    """The map loads, covers the area, and every model that moves robots keeps them off walls."""
    from netsim.world.maps import cached_map

    w = config.world
    if w.torus:
        raise ConfigError("world.map", w.map, "cannot be used with world.torus = true (a map does not wrap)")
    area = world_bounds(w)
    cached_map(w.map).check_area(area, bounds_given=w.bounds_m != "map" and "bounds_m" not in w.derived)
    if w.placement == "centre":
        w.check_centre(area)
    mobility = config.mobility
    if mobility.plugin.moves_robots and not getattr(mobility.plugin, "respects_map", False):
        raise ConfigError(
            "world.map", w.map, f"mobility.model = {mobility.model!r} cannot keep robots off the map's walls"
        )


# -- the controllers' sections -------------------------------------------------------------
def _enabled_by_section(plugin: Any) -> bool:
    return "enabled" in names(plugin.Params)


def _section_taken(section: str) -> bool:
    return section in ENGINE_SECTIONS or section in ("seed", "duration_s") or hasattr(Config, section)


_LEFT_OUT_TOLD: set[str] = set()


def section_owners(control: ControlParams) -> dict[str, Any]:
    """The plugins that own a section, by section name: the controllers ``control.controllers``
    names that do, then every installed controller that does (switched on by its ``enabled``
    key). An installed controller the configuration does not name, whose section the engine
    or another controller already uses, is left out with a warning: a plugin that cannot be
    offered stops no run that does not name it."""
    owners: dict[str, Any] = {}
    owner_name: dict[str, str] = {}
    installed = list(plugins.registered(plugins.CONTROLLERS).items())
    registered = {id(p) for _, p in installed}
    key = "control.controllers"
    for name in control.controllers:
        plugin = plugins.resolve(plugins.CONTROLLERS, name, key)
        section = plugin.Params.section
        if id(plugin) in registered and section and _enabled_by_section(plugin):
            raise ConfigError(key, name, f"is switched on by {section}.enabled = true, not listed here")
        if not section:
            continue
        if _section_taken(section):
            raise ConfigError(key, name, f"declares the section [{section}], a name the engine uses")
        if owners.get(section, plugin) is not plugin:
            raise ConfigError(key, name, f"declares the section [{section}], as {owner_name[section]!r} does")
        owners[section], owner_name[section] = plugin, name
    for name, plugin in installed:
        section = plugin.Params.section
        if not section or owners.get(section) is plugin:
            continue
        if _section_taken(section) or section in owners:
            other = "the engine" if _section_taken(section) else repr(owner_name[section])
            told = f"installed controller {name!r} is left out: its section [{section}] is used by {other}"
            if told not in _LEFT_OUT_TOLD:  # once a process: the owners are asked for often
                _LEFT_OUT_TOLD.add(told)
                warnings.warn(told, stacklevel=2)
            continue
        owners[section], owner_name[section] = plugin, name
    return owners


def _sections(control: ControlParams, given: dict[str, Any]) -> dict[str, Params]:
    owners = section_owners(control)
    for name in given:
        if name not in owners:
            raise ConfigError(name, given[name], "no active plugin owns this section")
    out = {}
    for name, plugin in owners.items():
        params = given.get(name)
        if params is None:
            params = plugin.Params()
        elif type(params) is not plugin.Params:
            raise ConfigError(name, params, f"must be {plugin.Params.__name__}")
        out[name] = params
    return out


def controllers(config: Config) -> list[tuple[str, Any, Params]]:
    """The controllers a run builds, in order, as ``(name, plugin, params)``: the registered
    controllers whose section has an ``enabled`` key, when it is true; then those
    ``control.controllers`` names."""
    out = []
    owners = section_owners(config.control)
    for plugin in plugins.registered(plugins.CONTROLLERS).values():
        section = plugin.Params.section
        if not (section and _enabled_by_section(plugin) and owners.get(section) is plugin):
            continue  # no switch of its own, or left out (section_owners)
        if config.sections[section].enabled:  # type: ignore[attr-defined]
            out.append((section, plugin, config.sections[section]))
    for name in config.control.controllers:
        plugin = plugins.resolve(plugins.CONTROLLERS, name, "control.controllers")
        section = plugin.Params.section
        out.append((name, plugin, config.sections[section] if section else plugin.Params()))
    return out


# -- from TOML -------------------------------------------------------------------------------
def _table(raw: Mapping, name: str) -> dict:
    value = raw.get(name, {})
    if not isinstance(value, dict):
        raise ConfigError(name, value, f"must be a table ([{name}])")
    return value


def _unknown(key: str, value: Any, allowed: Iterable[str], others: Iterable[str] = ()) -> ConfigError:
    """An unknown key, with the keys ``allowed`` and those the section takes with another
    model (``others``): a key of a model not chosen is taken, and ignored with a warning."""
    allowed = sorted(allowed)
    others = sorted(set(others) - set(allowed))
    said = f"unknown key{did_you_mean(key.rsplit('.', 1)[-1], allowed + others)}; allowed: " + ", ".join(allowed)
    if others:
        said += "; with another model: " + ", ".join(others)
    return ConfigError(key, value, said)


def _plain_section(cls: type[Params], raw: dict) -> Params:
    allowed = names(cls)
    for key in raw:
        if key not in allowed:
            raise _unknown(f"{cls.section}.{key}", raw[key], allowed)
    return cls(**raw)


def _other_keys(group_params: Mapping[str, type[Params]], chosen: str) -> dict[str, list[str]]:
    """Key -> the other models of the section that have it."""
    out: dict[str, list[str]] = {}
    for name, cls in group_params.items():
        if name != chosen:
            for key in names(cls):
                out.setdefault(key, []).append(name)
    return out


def _split(section: str, raw: dict, own: list[str], chosen: str, params_cls: type, others: dict) -> dict:
    """The keys of ``raw`` that ``params_cls`` takes; keys of another model are dropped with
    a warning; any other key is an error."""
    mine = names(params_cls)
    taken, ignored = {}, []
    for key, value in raw.items():
        if key in own:
            continue
        if key in mine:
            taken[key] = value
        elif key in others:
            ignored.append(key)
        else:
            raise _unknown(f"{section}.{key}", value, own + mine, others)
    if ignored:
        which = ", ".join(f"{section}.{k}" for k in ignored)
        warnings.warn(
            f"{which}: not used by {chosen!r} (a key of {', '.join(sorted({m for k in ignored for m in others[k]}))});"
            " ignored",
            ConfigWarning,
            stacklevel=4,
        )
    return taken


def _model_section(cls: type[ModelSection], raw: dict) -> ModelSection:
    key = f"{cls.section}.model"
    model = raw["model"] if "model" in raw else plugins.default_name(cls.group)
    if not isinstance(model, str):
        raise ConfigError(key, model, "must be a string")
    plugin = plugins.resolve(cls.group, model, key)
    declared = plugin.Params.section
    if declared in ENGINE_SECTIONS and declared != cls.section:
        # Its keys live in another model's section: a model of another kind, named here by mistake.
        raise ConfigError(key, model, f"its keys are of [{declared}]: not a {cls.section} model")
    group = {name: p.Params for name, p in plugins.registered(cls.group).items()}
    taken = _split(cls.section, raw, ["model"], model, plugin.Params, _other_keys(group, model))
    required = [
        f.name
        for f in dataclasses.fields(plugin.Params)
        if f.init and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    for name in required:
        if name not in taken:
            # A plugin's key without a default is the user's to give.
            raise ConfigError(f"{cls.section}.{name}", None, f"must be set: {key} = {model!r} gives it no default")
    return cls(model, plugin.Params(**taken))


def _channel_section(raw: dict) -> ChannelParams:
    """``[channel]``: its own keys, and those of the models it names (propagation, loss
    model, medium access); keys of the models not chosen are ignored with a warning, any
    other key is an error."""
    own = names(ChannelParams)
    chosen = {}
    for key, group, attr in CHANNEL_MODELS:
        name = _model_name(group, key)(f"channel.{key}", raw.get(key, getattr(ChannelParams, key)))
        chosen[attr] = (key, name, plugins.resolve(group, name, f"channel.{key}").Params)
    taken: dict[str, dict] = {attr: {} for attr in chosen}
    ignored: dict[str, list[str]] = {attr: [] for attr in chosen}
    others = {
        attr: _other_keys({n: m.Params for n, m in plugins.registered(group).items()}, chosen[attr][1])
        for _, group, attr in CHANNEL_MODELS
    }
    for k, v in raw.items():
        if k in own:
            continue
        mine = [attr for attr, (_, _, cls) in chosen.items() if k in names(cls)]
        for attr in mine:
            taken[attr][k] = v
        if mine:
            continue
        other = [attr for attr in chosen if k in others[attr]]
        if not other:
            mine_all = own + [n for _, _, cls in chosen.values() for n in names(cls)]
            raise _unknown(f"channel.{k}", v, mine_all, [n for attr in chosen for n in others[attr]])
        ignored[other[0]].append(k)
    params = {attr: cls(**taken[attr]) for attr, (_, _, cls) in chosen.items()}
    propagation = plugins.resolve(PROPAGATION, chosen["radio"][1], "channel.propagation")
    if "range_m" in raw and propagation.ranges(params["radio"]) is not None:
        ignored["radio"].append("range_m")
    for attr, keys in ignored.items():
        if keys:
            key, name, _ = chosen[attr]
            owners = sorted({m for k in keys for m in others[attr].get(k, [])})
            whose = f" (a key of {', '.join(owners)})" if owners else ""
            warnings.warn(
                f"{', '.join('channel.' + k for k in keys)}: not used by channel.{key} = {name!r}{whose}; ignored",
                ConfigWarning,
                stacklevel=3,
            )
    values = {k: raw[k] for k in own if k in raw and k not in ignored["radio"]}
    return ChannelParams(**values, **params)


def from_dict(raw: Mapping) -> Config:
    """Build and validate a :class:`Config` from a nested dict (as TOML gives). Its
    warnings (keys ignored) are given once it is valid: a refused configuration is one
    error, not warnings about keys of a run that will not be."""
    with warnings.catch_warnings(record=True) as caught:
        config = _from_dict(raw)
    for w in caught:
        # Given from the caller's line, as a warning of from_dict's own: once per place.
        warnings.warn(w.message, w.category, stacklevel=2)
    return config


def _from_dict(raw: Mapping) -> Config:
    if not isinstance(raw, dict):
        raise ConfigError("<config>", raw, "must be a table")
    control = _plain_section(ControlParams, _table(raw, "control"))
    assert isinstance(control, ControlParams)
    owners = section_owners(control)
    allowed = ["seed", "duration_s", *ENGINE_SECTIONS, *owners]
    for key, value in raw.items():
        if key == "bridge":
            raise NetsimInputError("[bridge]: a table of `netsim bridge` (docs/ros2.md); run this scenario with it")
        if key not in allowed:
            raise _unknown(key, value, allowed)
    values: dict[str, Any] = {k: raw[k] for k in ("seed", "duration_s") if k in raw}
    values["world"] = _plain_section(WorldParams, _table(raw, "world"))
    values["mobility"] = _model_section(MobilitySection, _table(raw, "mobility"))
    values["channel"] = _channel_section(_table(raw, "channel"))
    values["protocol"] = _model_section(ProtocolSection, _table(raw, "protocol"))
    values["traffic"] = _plain_section(TrafficParams, _table(raw, "traffic"))
    values["control"] = control
    values["events"] = _plain_section(EventsParams, _table(raw, "events"))
    values["output"] = _plain_section(OutputParams, _table(raw, "output"))
    values["sections"] = {name: _plain_section(plugin.Params, _table(raw, name)) for name, plugin in owners.items()}
    values["channel"] = _without_walls_unless_a_map(values["channel"], values["world"])
    return Config(**values)


def _without_walls_unless_a_map(channel: ChannelParams, world: WorldParams) -> ChannelParams:
    """A wall loss set (other than its default) where no map puts walls is warned of and
    taken out, as other ignored keys are: a channel fitted on a map (`netsim calibrate
    --map`) run in open space would lose its walls unsaid, and the run's config.toml keeps
    no value that did nothing."""
    radio = channel.radio
    wall_loss_db = getattr(radio, "wall_loss_db", None)
    if world.map or wall_loss_db is None:
        return channel
    default = getattr(type(radio)(), "wall_loss_db", None)
    if wall_loss_db == default:
        return channel
    warnings.warn(
        f"channel.wall_loss_db = {wall_loss_db:g}: no walls without a map (world.map); ignored",
        ConfigWarning,
        stacklevel=3,
    )
    return dataclasses.replace(channel, radio=dataclasses.replace(radio, **{"wall_loss_db": default}))


# -- to TOML ---------------------------------------------------------------------------------
def _params_dict(params: Params, derived: bool) -> dict:
    out = {k: plain(v) for k, v in params.items(derived)}
    return out


def section_dict(value: Any, derived: bool = True) -> dict:
    """One section as a dict of plain TOML values."""
    if isinstance(value, ModelSection):
        return {"model": value.model, **_params_dict(value.params, derived)}
    if isinstance(value, ChannelParams):
        own = _params_dict(value, derived)
        if value.propagation_model.ranges(value.radio) is not None:
            del own["range_m"]  # the radio implies the range
        models = (_params_dict(value.medium, derived), _params_dict(value.radio, derived))
        return {**own, **models[0], **models[1], **_params_dict(value.loss, derived)}
    return _params_dict(value, derived)


def to_dict(config: Config, derived: bool = True) -> dict:
    """The configuration as a nested dict of plain TOML values, sections in order; without
    the values derived from other keys if ``derived`` is false."""
    out: dict[str, Any] = {"seed": config.seed, "duration_s": config.duration_s}
    for name in ("world", "mobility", "channel", "protocol", "traffic"):
        out[name] = section_dict(getattr(config, name), derived)
    for name, params in config.sections.items():
        out[name] = section_dict(params, derived)
    for name in ("control", "events", "output"):
        out[name] = section_dict(getattr(config, name), derived)
    return out


def _as_tree(value: Any) -> Any:
    if isinstance(value, Config):
        return to_dict(value, derived=False)
    if isinstance(value, ModelSection | Params):
        return section_dict(value, derived=False)
    return value


def merge(base: dict, extra: dict) -> dict:
    """Deep-merge ``extra`` into a copy of ``base``."""
    out = dict(base)
    for k, v in extra.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


def override_key(text: str) -> str:
    """The key a ``--set`` names: ``"world.n_robots"`` of ``" world.n_robots = 8"``."""
    return text.partition("=")[0].strip()


def _check_override_path(raw: dict, text: str) -> None:
    """``--set a.b.c=v`` over a file where ``a`` (or ``a.b``) holds a value, not a table:
    the merge would drop that value without a word. A section of the configuration given a
    value in the file is the file's mistake; any other key is the ``--set``'s (it names a
    key as if it were a section)."""
    parts = override_key(text).split(".")
    node: Any = raw
    for depth, part in enumerate(parts[:-1]):
        if not isinstance(node, dict) or part not in node:
            return
        node = node[part]
        if not isinstance(node, dict):
            prefix = ".".join(parts[: depth + 1])
            if depth == 0 and part not in ("seed", "duration_s"):
                raise ConfigError(prefix, node, "must be a table (a [section] of keys)")
            raise ConfigError("--set", text, f"{prefix} is a key, not a section")


def parse_override(text: str) -> dict:
    """Turn ``"mobility.speed_max_mps=10"`` into ``{"mobility": {"speed_max_mps": 10}}``.

    The value is read as a TOML value (numbers, booleans, quoted strings, lists, inline
    tables, ``inf``); a bare word that is not valid TOML is taken as a string, so ``--set
    world.placement=grid`` works without quotes. A value that starts like a list, a table
    or a quoted string but does not parse is an error, not a string.
    """
    if "=" not in text:
        raise ConfigError("--set", text, "must look like key=value or section.key=value")
    key, raw = override_key(text), text.partition("=")[2]
    if not key or any(not part for part in key.split(".")):
        raise ConfigError("--set", text, "must look like key=value or section.key=value")
    raw = raw.strip()
    try:
        parsed: Any = tomllib.loads(f"v = {raw}")
    except tomllib.TOMLDecodeError as exc:
        parsed = exc
    if isinstance(parsed, dict) and list(parsed) == ["v"] and "\n" not in raw and "\r" not in raw:
        value = parsed["v"]
    elif raw[:1] in _TOML_OPENERS or "\n" in raw or "\r" in raw:
        what = _TOML_OPENERS.get(raw[:1], "value")
        why = f" ({parsed})" if isinstance(parsed, Exception) else ""
        raise ConfigError(key, raw, f"is not a valid TOML {what}{why}")
    else:
        value = raw
    return nest(key, value)


_TOML_OPENERS = {"[": "list", "{": "inline table", '"': "string", "'": "string"}


def nest(dotted_key: str, value: Any) -> dict:
    """``nest("a.b.c", 1) == {"a": {"b": {"c": 1}}}``."""
    tree: dict = {}
    node = tree
    parts = dotted_key.split(".")
    for part in parts[:-1]:
        node = node.setdefault(part, {})
    node[parts[-1]] = value
    return tree


def load(path: str | Path | None = None, overrides: Iterable[str] = ()) -> Config:
    """Load a TOML file (or the built-in default scenario when ``path`` is None). An error
    of a key the file sets, and no ``--set`` does, names the file."""
    overrides = list(overrides) if not isinstance(overrides, (str, bytes)) else overrides
    tree = read_tree(path, overrides)
    try:
        return from_dict(tree)
    except ConfigError as exc:
        if path is not None and _set_in(read_tree(path), exc.key) and not _set_in(read_tree(None, overrides), exc.key):
            exc.source = str(path)
        raise


def _set_in(tree: dict, key: str) -> bool:
    """Whether the dotted ``key`` is set in ``tree`` (a scenario's keys as read)."""
    node: Any = tree
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def read_tree(path: str | Path | None = None, overrides: Iterable[str] = ()) -> dict:
    """A scenario file's keys as read, ``--set`` overrides merged in, not yet checked."""
    if isinstance(overrides, (str, bytes)):
        # A string is an iterable of its characters: each would be read as an override.
        raise TypeError(f"overrides = {overrides!r}: must be a list of 'key=value' strings, not one string")
    raw: dict = {}
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise ConfigError("scenario file", str(p), not_a_file(p))
        try:
            raw = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError("scenario file", str(p), f"is not valid TOML: {exc}") from None
    for text in overrides:
        override = parse_override(text)
        _check_override_path(raw, text)
        raw = merge(raw, override)
    return raw


# -- documentation ---------------------------------------------------------------------------
def _section_rows(section: str, value: Any) -> list[tuple[str, Any, str, bool]]:
    """(key, value, meaning, derived) of every key of one section of a configuration."""
    rows = []
    if isinstance(value, ModelSection):
        rows.append(("model", value.model, f"{section} model, by plugin name (or 'package.module:attr')", False))
        params: list[Params] = [value.params]
    elif isinstance(value, ChannelParams):
        params = [value, value.medium, value.radio, value.loss]
    else:
        params = [value]
    for p in params:
        docs = {name: doc for name, _, doc, _ in describe_params(type(p))}
        for name, v in p.items():
            rows.append((name, plain(v), docs[name], name in p.derived))
    return rows


def _rule(params_cls: type, name: str) -> str:
    return next(rule for key, _, _, rule in describe_params(params_cls) if key == name)


def _other_models(section: str) -> list[tuple[str, str, Any, str, str]]:
    """(model, key, default, meaning, rule) of the keys of the models a section could name
    but does not by default: the other registered mobility models, protocols, loss models
    (``rule``: how a derived default is derived, else "")."""
    if section in ("mobility", "protocol"):
        group = plugins.MOBILITY if section == "mobility" else plugins.PROTOCOLS
        models = {name: p.Params for name, p in plugins.registered(group).items()}
    elif section == "channel":
        models = {}
        for _, group, _ in CHANNEL_MODELS:
            models.update({name: m.Params for name, m in plugins.registered(group).items()})
    else:
        return []
    return [(model, k, d, doc, rule) for model, cls in models.items() for k, d, doc, rule in describe_params(cls)]


def commented_toml(config: Config | None = None) -> str:
    """The configuration as a TOML file with every key explained, ready to edit. Defaults
    derived from another key are written as the rule, commented out; the keys of the models
    the file does not choose follow each section, commented out."""
    import tomli_w

    config = config or Config()
    out = [
        f"# {Config.__dataclass_fields__['seed'].metadata['doc']}",
        tomli_w.dumps({"seed": config.seed}).strip(),
        f"# {Config.__dataclass_fields__['duration_s'].metadata['doc']}",
        tomli_w.dumps({"duration_s": config.duration_s}).strip(),
    ]
    tables: list[str] = []
    tree = to_dict(config)
    for section in tree:
        if section in ("seed", "duration_s"):
            continue
        value = getattr(config, section)
        out += ["", f"[{section}]"]
        used = set()
        owners = (
            [value.params]
            if isinstance(value, ModelSection)
            else [value] + ([value.medium, value.radio, value.loss] if isinstance(value, ChannelParams) else [])
        )
        for key, v, doc, is_derived in _section_rows(section, value):
            used.add(key)
            if isinstance(v, dict):
                # A sub-table cannot sit among the section's keys: it goes at the end.
                tables += ["", f"# {doc}", f"[{section}.{key}]"]
                tables += [tomli_w.dumps(v).strip()] if v else []
                continue
            line = tomli_w.dumps({key: v}).strip()
            if is_derived:
                # Written as the rule, not a number, so that it follows the key it derives from.
                rule = next(_rule(type(p), key) for p in owners if key in names(type(p)))
                if isinstance(v, list):
                    # One commented line, not TOML's one line per element.
                    items = (tomli_w.dumps({key: e}).split("=", 1)[1].strip() for e in v)
                    line = f"{key} = [{', '.join(items)}]"
                out += [f"# {doc}", f"# default: {rule}; uncomment to fix it", f"# {line}"]
                continue
            out += [f"# {doc}", line]
            if key == "model" and isinstance(value, ModelSection) and names(type(value.params)):
                # Left beside another model, they would be warned of at every run.
                out += [
                    f"# {v}'s own keys follow: with another model leave them out"
                    f" (`netsim config --set {section}.model=NAME` writes that model's)"
                ]
        others = [row for row in _other_models(section) if row[1] not in used]
        if others:
            what = (
                "propagation, loss and medium access models, used when propagation, loss_model or mac"
                if section == "channel"
                else f"{section} models, used when model"
            )
            out += ["", f"# keys of the other {what} names one of them:"]
            if section == "channel":
                # A key several media share (aloha's and csma's) is listed once.
                merged: dict[str, tuple[list[str], Any, str, str]] = {}
                for model, key, default, doc, rule in others:
                    merged.setdefault(key, ([], default, doc, rule))[0].append(model)
                others = [(", ".join(m), key, d, doc, rule) for key, (m, d, doc, rule) in merged.items()]
            for model, key, default, doc, rule in others:
                shown = tomli_w.dumps({key: plain(default)}).strip() if default is not None else f"{key} = ..."
                out.append(f"# {shown}    # ({model}) {doc}" + (f" (default: {rule})" if rule else ""))
    return "\n".join(out + tables) + "\n"


def describe(config: Config | None = None) -> list[tuple[str, object, str]]:
    """(key, default, meaning) of every key of ``config`` (default: the built-in one)."""
    config = config or Config()
    rows: list[tuple[str, object, str]] = [
        ("seed", config.seed, Config.__dataclass_fields__["seed"].metadata["doc"]),
        ("duration_s", config.duration_s, Config.__dataclass_fields__["duration_s"].metadata["doc"]),
    ]
    for section in to_dict(config):
        if section in ("seed", "duration_s"):
            continue
        rows += [(f"{section}.{k}", v, doc) for k, v, doc, _ in _section_rows(section, getattr(config, section))]
    return rows


def check_inputs(config: Config) -> None:
    """Refuse (:class:`ConfigError`) a file a section's model will read that is not there
    (:meth:`netsim.params.Params.inputs`)."""
    for value in (getattr(config, f.name) for f in dataclasses.fields(config)):
        sections = value.values() if isinstance(value, Mapping) else [value]
        for section in sections:
            params = section.params if isinstance(section, ModelSection) else section
            if not isinstance(params, Params):
                continue
            for key, path in params.inputs().items():
                if not Path(path).expanduser().exists():
                    raise ConfigError(key, path, not_a_file(Path(path).expanduser()))


def all_keys(config: Config | None = None) -> list[str]:
    """Every key a configuration may set: those of ``config`` and the keys of every
    registered model of its sections."""
    keys = [k for k, _, _ in describe(config)]
    for section in ("mobility", "channel", "protocol"):
        keys += [f"{section}.{k}" for _, k, _, _, _ in _other_models(section)]
    return list(dict.fromkeys(keys))


__all__ = [
    "ChannelParams",
    "Config",
    "ConfigWarning",
    "ControlParams",
    "EventsParams",
    "MobilitySection",
    "ModelSection",
    "NoParams",
    "OutputParams",
    "ProtocolSection",
    "WorldParams",
    "all_keys",
    "check_inputs",
    "commented_toml",
    "controllers",
    "describe",
    "from_dict",
    "load",
    "merge",
    "nest",
    "parse_override",
    "section_owners",
    "to_dict",
]
