"""The world the robots move in, beside the area (:mod:`netsim.area`): the team's occupancy
maps (:mod:`netsim.world.maps`), free space and destinations drawn over it
(:mod:`netsim.world.free_space`), line of sight through a map's cells (:mod:`netsim.world.los`)
and the sweeps of moving segments across them (:mod:`netsim.world.sweep`). It builds on the
engine's base only: the radio, the link solvers and the mobility models build on it.
"""
