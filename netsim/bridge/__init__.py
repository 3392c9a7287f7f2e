"""ROS 2 robots on the simulated network (``netsim bridge``, docs/ros2.md), and the live
view of a run in Foxglove (``--live``).

- :mod:`~netsim.bridge.settings`: the ``[bridge]`` table and the command's checks; needs
  neither DDS nor Foxglove, so bad input is refused before either is loaded;
- :mod:`~netsim.bridge.messages`: the ROS 2 message types as Cyclone DDS structures;
- :mod:`~netsim.bridge.relay`: robots' own traffic through the simulated channel;
- :mod:`~netsim.bridge.node`: the DDS participant (topics, QoS);
- :mod:`~netsim.bridge.loop`: the run paced against the wall clock;
- :mod:`~netsim.bridge.live_view`: the Foxglove WebSocket server.

The commands themselves (``netsim bridge``, ``netsim run --live``) are in
:mod:`netsim.tools.bridge`, with the other commands: the engine's modules never import the tools.

Nothing here is imported by ``netsim run`` unless it is given ``--live``; ``cyclonedds``
and ``foxglove`` (the optional extra ``ros``) are imported only by the modules that use them.
"""
