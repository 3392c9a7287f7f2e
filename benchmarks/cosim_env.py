"""Benchmark: agent-steps per second of the coverage environment (netsim.envs.coverage_v0).

Workload: N = 20 robots (the environment's defaults: side 400 m, range 50 m, a dense start),
the clustering protocol with Acks at 1 Hz, one step per second, random actions drawn up
front (the policy costs nothing), episodes of ``--cycles`` steps. The first episode is a
warm-up (numba loads its compiled loops); the rate is over the next ``--episodes``, resets
included, by the wall clock and by the process's CPU time (on a shared machine the two
differ by the share of a core the process got), and each part of a step is timed apart (wall
clock): the network (drive and run), the observations, the measures (covered fraction,
components).

    python benchmarks/cosim_env.py                   # N = 20
    python benchmarks/cosim_env.py --n 20 50 --episodes 3
    python benchmarks/cosim_env.py --gc-freeze       # the imports frozen out of the collector
"""

from __future__ import annotations

import time

import numpy as np

from netsim.tools.args import Parser


def measure_rate(n: int, cycles: int, episodes: int, freeze: bool = False) -> dict:
    import gc

    from netsim.envs import coverage_v0

    env = coverage_v0.parallel_env(n_robots=n, max_cycles=cycles)
    rng = np.random.default_rng(0)
    agents = env.possible_agents
    actions = [dict(zip(agents, rng.uniform(-2.0, 2.0, (n, 2)).astype(np.float32))) for _ in range(64)]

    def episode(seed: int) -> int:
        env.reset(seed=seed)
        k = 0
        while env.agents:
            env.step(actions[k % len(actions)])
            k += 1
        return k

    episode(0)
    if freeze:
        # What the imports and the first episode left (numba, pandas, ...) out of the
        # collector's passes, once, as a training script may do after making its environment.
        gc.freeze()
    start, cpu = time.perf_counter(), time.process_time()
    steps = sum(episode(1 + e) for e in range(episodes))
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    # The parts of a step, timed apart on one more episode.
    env.reset(seed=99)
    sim = env.sim
    ids = np.arange(n)
    velocities = [np.array(list(a.values()), dtype=float) for a in actions]
    t0 = time.perf_counter()
    for k in range(cycles):
        sim.drive(ids, velocities[k % len(velocities)])
        sim.run(until_s=k + 1.0, steps=1)
    network = (time.perf_counter() - t0) / cycles
    pos = sim.positions()
    t0 = time.perf_counter()
    for _ in range(cycles):
        env._observations(pos)
    observe = (time.perf_counter() - t0) / cycles
    t0 = time.perf_counter()
    for _ in range(cycles):
        env._covered(pos)
        env._components(pos)
    score = (time.perf_counter() - t0) / cycles
    return {
        "n": n,
        "steps": steps,
        "wall_s": wall,
        "agent_steps_per_s": steps * n / wall,
        "agent_steps_per_cpu_s": steps * n / cpu,
        "network_us": network * 1e6,
        "observe_us": observe * 1e6,
        "measure_us": score * 1e6,
        "step_us": wall / steps * 1e6,
    }


def main() -> None:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[20])
    parser.add_argument("--cycles", type=int, default=200)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument(
        "--gc-freeze", action="store_true", help="gc.freeze() once after the warm-up episode (docs/cosim.md, Speed)"
    )
    args = parser.parse_args()
    print("N  agent-steps/s  per CPU s  step us  network us  observations us  measures us")
    for n in args.n:
        r = measure_rate(n, args.cycles, args.episodes, args.gc_freeze)
        print(
            f"{r['n']:<3d}{r['agent_steps_per_s']:>13,.0f}  {r['agent_steps_per_cpu_s']:>9,.0f}  "
            f"{r['step_us']:>7.0f}  {r['network_us']:>10.0f}  "
            f"{r['observe_us']:>15.0f}  {r['measure_us']:>11.0f}"
        )


if __name__ == "__main__":
    main()
