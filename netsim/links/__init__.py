"""Link solving: when each pair of robots is linked.

- :mod:`netsim.links.crossings`: the crossings of a pair's relative path with a disk, the
  arithmetic every solver shares (compiled in :mod:`netsim.links._kernels`);
- :mod:`netsim.links.lifetimes`: exact link lifetimes solved after the run (the reference);
- :mod:`netsim.links.kinetic`: the same links solved during the run, announced as
  ``link_up`` and ``link_down`` events at their instants;
- :mod:`netsim.links.radio_links`: link lifetimes under a log-distance radio (walls,
  and the record of the channel's decisions under shadowing);
- :mod:`netsim.links.shadowed_links`: runtime link events under shadowing, from the
  channel's decisions;
- :mod:`netsim.links.walled_links` and :mod:`netsim.links.wall_sweeps`: runtime link
  events on a map, where walls cut links, solved exactly on the walls' sweep
  (:mod:`netsim.world.sweep`).

The solvers read the robots' legs and the radio's reception decision
(:mod:`netsim.radio`); nothing in the radio imports them.
"""
