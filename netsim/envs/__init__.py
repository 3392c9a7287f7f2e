"""Environments for learning to control the robots, in PettingZoo's parallel API and, by
its conversion, its turn-based one (``env()``; docs/cosim.md): ``from netsim.envs import
coverage_v0``. They need the optional extra ``rl`` (``pip install -e ".[rl]"``)."""
