"""The channel: who hears a frame, when, and what is lost on the way.

- :mod:`netsim.radio.channel`: the :class:`~netsim.radio.channel.Channel`, the face the
  protocols send through (delays, delivery, drops, the loss model last);
- :mod:`netsim.radio.spatial`: who is within range of a robot now (a neighbour list);
- :mod:`netsim.radio.reception`: the reception decision of a radio, and its record of links;
- :mod:`netsim.radio.models`: what a propagation model, a loss model and a medium access
  control declare to be plugins (entry-point groups ``netsim.propagation``,
  ``netsim.loss``, ``netsim.mac``), and ``channel.mac = "none"``;
- :mod:`netsim.radio.propagation_models`: the built-in propagation models (unit disk,
  log-distance);
- :mod:`netsim.radio.chain`: received power as a chain of small loss terms, heard with the
  robots' radio (transmit power, sensitivity);
- :mod:`netsim.radio.propagation`: the two built-in chains (log-distance path loss,
  shadowing, walls, or a unit disk with line of sight), the radio's keys;
- :mod:`netsim.radio.fast`: those chains compiled into one pass;
- :mod:`netsim.radio.loss`: the built-in reception loss models;
- :mod:`netsim.radio.shadowing`: log-normal shadowing per pair, reciprocal, spatially
  correlated as robots move (Gudmundson's exponential model);
- :mod:`netsim.world.maps`: ROS ``map_server`` maps (YAML and PGM/PNG image);
- :mod:`netsim.world.los`: line of sight and walls crossed, for many segments at once;
- :mod:`netsim.world.free_space`: where robots may be and go on a map;
- :mod:`netsim.world.examples`: the example maps shipped with netsim;
- :mod:`netsim.radio.mac`: the shared medium (airtime and collisions, with ALOHA or
  CSMA/DCF as its access policy), and :mod:`netsim.radio.mac_models` its two models' keys;
- :mod:`netsim.radio._kernels`: the radio's loops, the path-loss law among them (computed
  there once, for every caller).

The closed-form checks of these models are tools (:mod:`netsim.tools.radio_checks`,
:mod:`netsim.tools.mac_checks`, run by ``netsim validate``). The package reads no
configuration file: each model gets its parameters (the ``[channel]`` section's
dataclasses) and its collaborators when the run is built. It imports the engine's base
(state, events, agenda, parameters) and never the run builder, the link solvers or the tools.
"""
