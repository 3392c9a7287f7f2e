"""Robots that do not move by themselves: they stay where they are placed, unless
controllers move them (the coverage controller does). On a map they are placed in free
cells."""

from netsim.params import NoParams
from netsim.placement import initial_positions
from netsim.plugins import Parts, PluginSpec


def build(params: NoParams, parts: Parts) -> None:
    parts.state.place(initial_positions(parts.world, parts.streams, parts.occupancy, parts.channel))


PLUGIN = PluginSpec(Params=NoParams, build=build, moves_robots=False, respects_map=True)
