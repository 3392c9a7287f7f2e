"""Run configuration: TOML files, ``--set`` overrides, validation.

A configuration is a tree of small frozen dataclasses. Every value is checked when it is
loaded; a bad one raises :class:`~netsim.errors.ConfigError` naming the key, the value
and what is allowed. Unknown keys are rejected, so a typo never passes silently.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from netsim.errors import ConfigError

Check = Callable[[Any], "str | None"]


def _positive(v):
    return None if v > 0 else "must be > 0"


def _non_negative(v):
    return None if v >= 0 else "must be >= 0"


def _probability(v):
    return None if 0 <= v <= 1 else "must be a probability in [0, 1]"


def _one_of(*names: str) -> Check:
    def check(v):
        return None if v in names else "must be one of " + ", ".join(repr(n) for n in names)

    return check


def _any(v):
    return None


def _param(default, check: Check = _any, doc: str = ""):
    return field(default=default, metadata={"check": check, "doc": doc})


@dataclass(frozen=True)
class WorldConfig:
    n_robots: int = _param(50, _positive, "number of robots N")
    side_m: float = _param(1000.0, _positive, "side of the square area A, metres")
    placement: str = _param(
        "uniform", _any, '"uniform", "grid", "centre", or a path to a CSV file with columns x_m,y_m'
    )
    centre_side_m: float = _param(250.0, _positive, 'placement = "centre": side of the central square, metres')
    torus: bool = _param(False, _any, "wrap the area's borders (distances taken on a torus)")


@dataclass(frozen=True)
class MobilityConfig:
    model: str = _param("random_waypoint", _any, "mobility model, by plugin name")
    speed_min_mps: float = _param(0.5, _non_negative, "minimum speed, m/s")
    speed_max_mps: float = _param(5.0, _non_negative, "maximum speed, m/s")
    pause_s: float = _param(2.0, _non_negative, "pause at each waypoint, s")
    stationary_start: bool = _param(True, _any, "start in the stationary regime (no warm-up)")
    trace_file: str = _param("", _any, "ns-2 movement file replayed by model = 'trace'")
    turn_interval_s: float = _param(math.inf, _positive, "random direction on a torus: time between turns (inf: never)")


@dataclass(frozen=True)
class ChannelConfig:
    range_m: float | tuple[float, ...] = _param(
        150.0, _any, "communication range r_c in metres, or a list of one range per robot"
    )
    latency_s: float = _param(0.001, _non_negative, "fixed delay of every transmission, s")
    latency_jitter_s: float = _param(0.0, _non_negative, "extra delay uniform on [0, jitter], s")
    loss_model: str = _param(
        "bernoulli",
        _one_of("bernoulli", "distance", "gilbert_elliott"),
        "loss model: bernoulli, distance or gilbert_elliott",
    )
    loss_probability: float = _param(0.0, _probability, "Bernoulli loss per reception (also the floor of 'distance')")
    loss_distance_exponent: float = _param(
        4.0, _positive, "'distance': reception probability (1 - p)(1 - (d / r)^exponent)"
    )
    ge_p_good_to_bad: float = _param(0.05, _probability, "Gilbert-Elliott: P(good -> bad)")
    ge_p_bad_to_good: float = _param(0.5, _probability, "Gilbert-Elliott: P(bad -> good)")
    ge_loss_good: float = _param(0.0, _probability, "Gilbert-Elliott: loss in the good state")
    ge_loss_bad: float = _param(1.0, _probability, "Gilbert-Elliott: loss in the bad state")


@dataclass(frozen=True)
class ProtocolConfig:
    model: str = _param("clustering", _any, "protocol stack, by plugin name ('ack': beacons only)")
    ack_period_s: float = _param(1.0, _positive, "Ack period t, s")
    ack_jitter_s: float = _param(0.05, _non_negative, "each period is t + U(-jitter, +jitter), s")
    tau_s: float = _param(3.0, _positive, "liveness timeout tau, s (default 3 ack periods)")
    join_policy: str = _param(
        "nearest", _one_of("nearest", "first_heard", "lowest_id"), "rule 2: which leader an undecided robot joins"
    )
    merge_policy: str = _param(
        "smaller_group_yields",
        _one_of("smaller_group_yields", "lowest_id_wins", "highest_degree_wins"),
        "rule 5: which of two neighbouring leaders yields",
    )
    merge_delay_s: float = _param(
        2.0, _non_negative, "rule 5: how long two leaders must be linked, s (default 2 periods)"
    )
    election_policy: str = _param(
        "lowest_id", _one_of("lowest_id", "highest_degree", "none"), "rule 6: who replaces a lost leader"
    )
    routing: str = _param("backbone", _one_of("backbone", "oracle"), "message relaying: backbone flooding or oracle")
    distributed_gateways: bool = _param(
        True, _any, "members next to a member of another group relay too (keeps flooding connected)"
    )
    message_ttl: int = _param(32, _positive, "hops a relayed message may take")
    message_rate_hz: float = _param(0.2, _non_negative, "messages sent per second, network-wide (random pairs)")


@dataclass(frozen=True)
class CoverageConfig:
    enabled: bool = _param(False, _any, "the team spreads out by virtual forces (needs mobility.model = 'static')")
    members: str = _param(
        "spread",
        _one_of("spread", "follow"),
        "'spread': every robot is pushed apart, a spanning forest kept; 'follow': members follow their leader",
    )
    law: str = _param(
        "spring", _one_of("spring", "repulsion", "inverse_square"), "force law between neighbouring leaders"
    )
    knowledge: str = _param(
        "acks", _one_of("acks", "global"), "leaders' positions: as heard in Acks (stale), or the true ones"
    )
    control_period_s: float = _param(1.0, _positive, "time between control steps, s (also for control.controllers)")
    start_s: float = _param(10.0, _non_negative, "first control step, s (after the groups have formed)")
    gain: float = _param(0.1, _positive, "a leader's velocity is gain x resultant force, 1/s (forces in metres)")
    speed_max_mps: float = _param(2.0, _positive, "speed cap of every controlled robot, m/s")
    margin_m: float = _param(1.0, _non_negative, "kept links stay this far inside the range, m")
    stop_speed_mps: float = _param(0.02, _non_negative, "a leader whose force asks for less than this holds, m/s")
    stop_hold_s: float = _param(20.0, _positive, "control ends once every leader has held this long, s")
    stop_gain: float = _param(
        0.002, _non_negative, "spread: control ends once coverage gains less than this in stop_hold_s (0: off)"
    )
    radius_m: float = _param(0.0, _non_negative, "radius of the coverage disks, m (0: the communication range r_c)")
    metrics_interval_s: float = _param(5.0, _positive, "coverage metrics sampling interval, s")
    area_method: str = _param(
        "exact", _one_of("exact", "grid"), "covered fraction over time: 'exact' (polygon bracket) or 'grid' (cheap)"
    )
    grid_cells: int = _param(200, _positive, "area_method = 'grid': grid cells per side (error bound reported)")


@dataclass(frozen=True)
class ControlConfig:
    controllers: tuple[str, ...] = field(
        default=(),
        metadata={"check": _any, "doc": "user controllers and hooks, by plugin name or 'package.module:function'"},
    )
    options: dict = field(
        default_factory=dict, metadata={"check": _any, "doc": "free table of options for user controllers"}
    )


@dataclass(frozen=True)
class OutputConfig:
    position_interval_s: float = _param(1.0, _non_negative, "positions sampling interval (0: off)")


@dataclass(frozen=True)
class Config:
    seed: int = _param(1, _non_negative, "seed of every random stream")
    duration_s: float = _param(300.0, _positive, "simulated time, s")
    world: WorldConfig = field(default_factory=WorldConfig)
    mobility: MobilityConfig = field(default_factory=MobilityConfig)
    channel: ChannelConfig = field(default_factory=ChannelConfig)
    protocol: ProtocolConfig = field(default_factory=ProtocolConfig)
    coverage: CoverageConfig = field(default_factory=CoverageConfig)
    control: ControlConfig = field(default_factory=ControlConfig)
    output: OutputConfig = field(default_factory=OutputConfig)

    def replace(self, **sections) -> Config:
        """A copy with whole sections or top-level values replaced (validated again)."""
        return from_dict(merge(to_dict(self), to_dict_partial(sections)))

    def ranges_m(self):
        """Per-robot ranges as a tuple of floats, one per robot."""
        r = self.channel.range_m
        if isinstance(r, tuple):
            return r
        return (float(r),) * self.world.n_robots


_SECTION_CLASSES = {
    "world": WorldConfig,
    "mobility": MobilityConfig,
    "channel": ChannelConfig,
    "protocol": ProtocolConfig,
    "coverage": CoverageConfig,
    "control": ControlConfig,
    "output": OutputConfig,
}


def _coerce(key: str, value, default):
    """Check ``value`` has the type of ``default``; ints are accepted for floats."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(key, value, "must be true or false")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(key, value, "must be an integer")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(key, value, "must be a number")
        try:
            value = float(value)
        except OverflowError:
            raise ConfigError(key, value, "is too large for a number") from None
        if math.isnan(value):
            raise ConfigError(key, value, "must be a number, not NaN")
        return value
    if not isinstance(value, str):
        raise ConfigError(key, value, "must be a string")
    return value


def _build_section(cls, raw: dict, prefix: str):
    if not isinstance(raw, dict):
        raise ConfigError(prefix, raw, "must be a table ([" + prefix + "])")
    names = {f.name: f for f in dataclasses.fields(cls)}
    for key in raw:
        if key not in names:
            raise ConfigError(f"{prefix}.{key}", raw[key], "unknown key; allowed: " + ", ".join(sorted(names)))
    values = {}
    for name, f in names.items():
        key = f"{prefix}.{name}" if prefix else name
        if name not in raw:
            continue
        value = raw[name]
        if key == "channel.range_m" and isinstance(value, list):
            value = tuple(_coerce(f"{key}[{i}]", v, 1.0) for i, v in enumerate(value))
            for i, v in enumerate(value):
                if not (v > 0 and math.isfinite(v)):
                    raise ConfigError(f"{key}[{i}]", v, "must be a finite number > 0 (metres)")
        elif key == "control.controllers":
            if not isinstance(value, list):
                raise ConfigError(key, value, "must be a list of plugin names")
            value = tuple(_coerce(f"{key}[{i}]", v, "") for i, v in enumerate(value))
        elif key == "control.options":
            if not isinstance(value, dict):
                raise ConfigError(key, value, "must be a table ([control.options])")
            value = dict(value)
        else:
            value = _coerce(key, value, f.default)
            problem = f.metadata["check"](value)
            if problem:
                raise ConfigError(key, value, problem + _unit_hint(f))
        values[name] = value
    return cls(**values)


def _unit_hint(f) -> str:
    doc = f.metadata.get("doc", "")
    return f" ({doc})" if doc else ""


# Keys whose default follows protocol.ack_period_s, as a multiple of it.
DERIVED_FROM_ACK_PERIOD = {"tau_s": 3.0, "merge_delay_s": 2.0}


def from_dict(raw: dict) -> Config:
    """Build and validate a :class:`Config` from a nested dict (as TOML gives)."""
    if not isinstance(raw, dict):
        raise ConfigError("<config>", raw, "must be a table")
    top = {f.name: f for f in dataclasses.fields(Config) if f.name not in _SECTION_CLASSES}
    values: dict[str, Any] = {}
    for key, value in raw.items():
        if key in _SECTION_CLASSES:
            values[key] = _build_section(_SECTION_CLASSES[key], value, key)
        elif key in top:
            v = _coerce(key, value, top[key].default)
            problem = top[key].metadata["check"](v)
            if problem:
                raise ConfigError(key, v, problem + _unit_hint(top[key]))
            values[key] = v
        else:
            allowed = sorted(list(top) + list(_SECTION_CLASSES))
            raise ConfigError(key, value, "unknown key; allowed: " + ", ".join(allowed))
    protocol_raw = raw.get("protocol", {})
    if "protocol" in values:
        period = values["protocol"].ack_period_s
        scaled = {k: m * period for k, m in DERIVED_FROM_ACK_PERIOD.items() if k not in protocol_raw}
        if scaled:
            values["protocol"] = dataclasses.replace(values["protocol"], **scaled)
    config = Config(**values)
    _check_across(config)
    return config


def _check_across(c: Config) -> None:
    """Rules that tie several keys together."""
    if not math.isfinite(c.duration_s):
        raise ConfigError("duration_s", c.duration_s, "must be finite")
    if not math.isfinite(c.world.side_m):
        raise ConfigError("world.side_m", c.world.side_m, "must be finite")
    m = c.mobility
    if m.speed_min_mps > m.speed_max_mps:
        raise ConfigError(
            "mobility.speed_min_mps",
            m.speed_min_mps,
            f"must not exceed mobility.speed_max_mps = {m.speed_max_mps}",
        )
    for key in ("speed_max_mps", "pause_s"):
        if not math.isfinite(getattr(m, key)):
            raise ConfigError(f"mobility.{key}", getattr(m, key), "must be finite")
    p = c.protocol
    ch = c.channel
    if not p.tau_s > p.ack_period_s:
        raise ConfigError("protocol.tau_s", p.tau_s, f"must be greater than protocol.ack_period_s = {p.ack_period_s}")
    if not p.ack_jitter_s < p.ack_period_s / 2:
        raise ConfigError(
            "protocol.ack_jitter_s",
            p.ack_jitter_s,
            f"must be less than half of protocol.ack_period_s = {p.ack_period_s}",
        )
    # Without any loss two Acks of a neighbour can be up to period + jitter + latency jitter
    # apart: a tau no longer than that times neighbours out for nothing.
    gap = p.ack_period_s + p.ack_jitter_s + ch.latency_jitter_s
    if p.model != "none" and not p.tau_s > gap:
        raise ConfigError(
            "protocol.tau_s",
            p.tau_s,
            "must be greater than protocol.ack_period_s + protocol.ack_jitter_s + channel.latency_jitter_s"
            f" = {gap:g}, the longest gap between two Acks without loss",
        )
    if isinstance(ch.range_m, tuple):
        if len(ch.range_m) != c.world.n_robots:
            raise ConfigError(
                "channel.range_m",
                f"<list of {len(ch.range_m)}>",
                f"a list must have one range per robot (world.n_robots = {c.world.n_robots})",
            )
    elif not (ch.range_m > 0 and math.isfinite(ch.range_m)):
        raise ConfigError("channel.range_m", ch.range_m, "must be a finite number > 0 (metres)")
    for key in ("latency_s", "latency_jitter_s"):
        if not math.isfinite(getattr(ch, key)):
            raise ConfigError(f"channel.{key}", getattr(ch, key), "must be finite")
    if c.world.torus and c.world.side_m <= 2 * (max(ch.range_m) if isinstance(ch.range_m, tuple) else ch.range_m):
        raise ConfigError("world.side_m", c.world.side_m, "on a torus must exceed twice the largest range_m")
    if c.world.placement == "centre" and c.world.centre_side_m > c.world.side_m:
        raise ConfigError(
            "world.centre_side_m", c.world.centre_side_m, f"must not exceed world.side_m = {c.world.side_m}"
        )
    cov = c.coverage
    if cov.enabled and m.model != "static":
        raise ConfigError(
            "coverage.enabled",
            True,
            f"needs mobility.model = 'static' (the controller moves the robots), not {m.model!r}",
        )
    lead = ch.latency_s + ch.latency_jitter_s
    if (cov.enabled or c.control.controllers) and not cov.control_period_s > lead:
        raise ConfigError(
            "coverage.control_period_s",
            cov.control_period_s,
            f"must exceed the channel's largest delay (latency_s + latency_jitter_s = {lead})",
        )
    if cov.enabled and cov.members == "spread" and cov.metrics_interval_s > cov.stop_hold_s:
        raise ConfigError(
            "coverage.metrics_interval_s",
            cov.metrics_interval_s,
            f"must not exceed coverage.stop_hold_s = {cov.stop_hold_s} (the stopping rule compares samples)",
        )
    if cov.enabled and c.world.torus:
        raise ConfigError("coverage.enabled", True, "is for a bounded area; set world.torus = false")
    if cov.enabled and c.protocol.model in ("none", "ack"):
        raise ConfigError(
            "coverage.enabled",
            True,
            f"needs a protocol that forms groups (protocol.model = 'clustering'), not {c.protocol.model!r}",
        )
    if m.model == "trace" and not m.trace_file:
        raise ConfigError("mobility.trace_file", m.trace_file, "must name a file when model = 'trace'")


def to_dict(config) -> dict:
    """The configuration as a nested dict of plain TOML values."""
    out = {}
    for f in dataclasses.fields(config):
        v = getattr(config, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = to_dict(v)
        elif isinstance(v, tuple):
            out[f.name] = list(v)
        else:
            out[f.name] = v
    return out


def to_dict_partial(values: dict) -> dict:
    return {k: (to_dict(v) if dataclasses.is_dataclass(v) else v) for k, v in values.items()}


def merge(base: dict, extra: dict) -> dict:
    """Deep-merge ``extra`` into a copy of ``base``."""
    out = dict(base)
    for k, v in extra.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


def parse_override(text: str) -> dict:
    """Turn ``"mobility.speed_max_mps=10"`` into ``{"mobility": {"speed_max_mps": 10}}``.

    The value is read as a TOML value (numbers, booleans, quoted strings, lists, inline
    tables, ``inf``); a bare word that is not valid TOML is taken as a string, so ``--set
    world.placement=grid`` works without quotes. A value that starts like a list, a table
    or a quoted string but does not parse is an error, not a string.
    """
    if "=" not in text:
        raise ConfigError("--set", text, "must look like section.key=value")
    key, _, raw = text.partition("=")
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise ConfigError("--set", text, "must look like section.key=value")
    raw = raw.strip()
    try:
        parsed = tomllib.loads(f"v = {raw}")
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


def nest(dotted_key: str, value) -> dict:
    """``nest("a.b.c", 1) == {"a": {"b": {"c": 1}}}``."""
    tree: dict = {}
    node = tree
    parts = dotted_key.split(".")
    for part in parts[:-1]:
        node = node.setdefault(part, {})
    node[parts[-1]] = value
    return tree


def load(path: str | Path | None = None, overrides: list[str] = ()) -> Config:
    """Load a TOML file (or the built-in default scenario when ``path`` is None)."""
    raw: dict = {}
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise ConfigError("<config file>", str(p), "no such file")
        try:
            raw = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError("<config file>", str(p), f"is not valid TOML: {exc}") from None
    for text in overrides:
        raw = merge(raw, parse_override(text))
    return from_dict(raw)


def commented_toml(config: Config | None = None) -> str:
    """The configuration as a TOML file with every key explained, ready to edit."""
    import tomli_w

    config = config or Config()
    tree = to_dict(config)
    out = []
    for f in dataclasses.fields(Config):
        if f.name in _SECTION_CLASSES:
            continue
        out += [f"# {f.metadata.get('doc', '')}", tomli_w.dumps({f.name: tree[f.name]}).strip()]
    tables = []
    for section, cls in _SECTION_CLASSES.items():
        out += ["", f"[{section}]"]
        for g in dataclasses.fields(cls):
            value = tree[section][g.name]
            if isinstance(value, dict):
                # A sub-table cannot sit among the section's keys: it goes at the end.
                tables += ["", f"# {g.metadata.get('doc', '')}", f"[{section}.{g.name}]"]
                tables += [tomli_w.dumps(value).strip()] if value else []
                continue
            line = tomli_w.dumps({g.name: value}).strip()
            factor = DERIVED_FROM_ACK_PERIOD.get(g.name) if section == "protocol" else None
            if factor is not None and value == factor * tree["protocol"]["ack_period_s"]:
                # Written as the rule, not a number, so that it follows an edited ack_period_s.
                out += [
                    f"# {g.metadata.get('doc', '')}",
                    f"# default: {factor:g} x ack_period_s; uncomment to fix it",
                    f"# {line}",
                ]
                continue
            out += [f"# {g.metadata.get('doc', '')}", line]
    return "\n".join(out + tables) + "\n"


def describe() -> list[tuple[str, object, str]]:
    """(key, default, meaning) for every configuration key, for documentation."""
    rows = []
    for f in dataclasses.fields(Config):
        if f.name in _SECTION_CLASSES:
            for g in dataclasses.fields(_SECTION_CLASSES[f.name]):
                default = g.default if g.default is not dataclasses.MISSING else g.default_factory()
                rows.append((f"{f.name}.{g.name}", default, g.metadata.get("doc", "")))
        else:
            rows.append((f.name, f.default, f.metadata.get("doc", "")))
    return rows
