"""What a run needs before it starts, checked before any work or any file: that it fits in
the machine's memory, and that the files its models read are there. ``netsim run`` and
every other command that runs a scenario ask it, and a sweep asks it of every point before
its first run."""

from __future__ import annotations

from netsim import config as cfgmod
from netsim.errors import ConfigError
from netsim.machine import gib, machine_memory_bytes


def check_run(config: cfgmod.Config, here: bool = True) -> None:
    """Refuse ``config`` in one line (:class:`~netsim.errors.ConfigError`) if it cannot run:
    more memory than the machine has (``here``: the run is on this machine, not on a
    scheduler's workers), or a file a model reads that is not there."""
    if here:
        check_fits_in_memory(config)
    cfgmod.check_inputs(config)


def least_memory_bytes(config: cfgmod.Config) -> int:
    """Memory a run of ``config`` holds whatever its models: the robots' state (every
    array RobotState keeps per robot) and, made at the end, the positions table (a row
    per robot and sample). The models, the trace and the other tables come on top."""
    import numpy as np

    from netsim.run import ENGINE_TABLES
    from netsim.samples import sample_count
    from netsim.state import RobotState

    state = RobotState(1, 1.0, 1.0)
    per_robot = sum(v.nbytes for v in vars(state).values() if isinstance(v, np.ndarray) and v.base is None)
    row = sum(np.dtype(t).itemsize for t in ENGINE_TABLES["positions"].values())
    samples = sample_count(config.output.position_interval_s, config.duration_s)
    return config.world.n_robots * (per_robot + samples * row)


# What a course change held in memory costs at least (a row of the leg log).
LEG_BYTES = 100


def check_legs_fit_in_memory(config: cfgmod.Config, have: int | None) -> None:
    """Refuse, before any work, a random waypoint run whose course changes cannot fit
    in memory: each robot changes course at least once per longest leg (the area's diagonal
    at the least speed, and a pause), so ``duration_s`` bounds their number from below.
    (A protocol's events are bounded by their own rule, netsim.params.refuse_events; a
    run of motion alone has only this.) ``have``: the machine's memory (None: unknown)."""
    m = config.mobility
    if have is None or m.model != "random_waypoint" or not m.speed_min_mps > 0:
        return
    longest_s = cfgmod.world_bounds(config.world).diagonal / m.speed_min_mps + m.pause_s
    legs = config.world.n_robots * (config.duration_s / longest_s)
    if legs * LEG_BYTES > have:
        raise ConfigError(
            "duration_s",
            config.duration_s,
            f"the scenario would hold at least {gib(int(legs * LEG_BYTES))} GiB of course changes (a robot changes "
            f"course at least every {longest_s:.3g} s, crossing the area at mobility.speed_min_mps and pausing "
            f"mobility.pause_s), more than this machine's {gib(have)} GiB of memory; shorten it, or enlarge the "
            "area, or raise the pause or lower the least speed",
        )


def check_fits_in_memory(config: cfgmod.Config) -> None:
    """Refuse, before any work, a run that cannot fit in the machine's memory (rather than
    build it for minutes and fail)."""
    have, need = machine_memory_bytes(), least_memory_bytes(config)
    if have is None or need <= have:
        check_legs_fit_in_memory(config, have)
        return
    n = config.world.n_robots
    sampled = config.output.position_interval_s > 0
    held = "the robots' state and positions.parquet's rows" if sampled else "the robots' state"
    advice = "or duration_s, or raise output.position_interval_s (0: no positions table)" if sampled else ""
    raise ConfigError(
        "world.n_robots",
        n,
        f"the run would hold at least {gib(need)} GiB ({held}, before any model's), more than this "
        f"machine's {gib(have)} GiB of memory; lower it{', ' if advice else ''}{advice}",
    )
