"""Robots that do not move."""

from mobility.placement import initial_positions


def install(sim) -> None:
    sim.state.place(initial_positions(sim))
