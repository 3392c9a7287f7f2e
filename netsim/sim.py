"""The simulation object: a SimPy environment with the robots, the channel and the trace."""

from __future__ import annotations

import simpy

from netsim.channel import Channel
from netsim.config import Config
from netsim.loss import BernoulliLoss, DistanceLoss, GilbertElliottLoss
from netsim.progress import progress_bar
from netsim.rng import Streams
from netsim.state import RobotState
from netsim.trace import Trace


def make_loss(config: Config, streams: Streams, state: RobotState):
    ch = config.channel
    rng = streams.get("channel.loss")
    if ch.loss_model == "distance":
        return DistanceLoss(ch.loss_probability, ch.loss_distance_exponent, state.range_m, rng)
    if ch.loss_model == "gilbert_elliott":
        return GilbertElliottLoss(
            ch.ge_p_good_to_bad, ch.ge_p_bad_to_good, ch.ge_loss_good, ch.ge_loss_bad, state.n, rng
        )
    return BernoulliLoss(ch.loss_probability, rng)


class Simulation:
    """One run: ``env`` (SimPy), ``state`` (robots), ``channel``, ``trace``, ``streams``.

    Models are installed on it by :func:`netsim.run.build` (or by hand, in tests and
    scripts) and keep what they return in :attr:`models`.
    """

    def __init__(self, config: Config, run: int = 0):
        self.config = config
        self.env = simpy.Environment()
        self.streams = Streams(config.seed, run)
        self.state = RobotState(config.world.n_robots, config.world.side_m, config.ranges_m(), config.world.torus)
        self.trace = Trace()
        ch = config.channel
        self.channel = Channel(
            self.env,
            self.state,
            make_loss(config, self.streams, self.state),
            ch.latency_s,
            ch.latency_jitter_s,
            self.streams.get("channel.latency"),
        )
        self.models: dict[str, object] = {}

    @property
    def now(self) -> float:
        return self.env.now

    def run(self, until_s: float | None = None, progress: bool = False, steps: int = 200) -> None:
        """Advance to ``until_s`` (default: the configured duration).

        Events due exactly at ``until_s`` are not processed (SimPy's convention); every
        output is computed for the interval ``[0, until_s]`` from exact trajectories.
        """
        until = self.config.duration_s if until_s is None else float(until_s)
        start = self.env.now
        with progress_bar(
            round(until - start, 6),
            "netsim run",
            "sim s",
            enabled=progress,
            leave=False,
            bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} sim s [{elapsed}<{remaining}]",
        ) as bar:
            for k in range(1, steps + 1):
                t = start + (until - start) * k / steps
                if t > self.env.now:
                    before = self.env.now
                    self.env.run(until=t)
                    bar.update(self.env.now - before)
