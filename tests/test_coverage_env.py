"""The PettingZoo environment netsim.envs.coverage_v0 (docs/cosim.md)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from matplotlib.backend_bases import FigureCanvasBase  # noqa: E402
from pettingzoo.test import parallel_api_test, parallel_seed_test  # noqa: E402

from netsim import _kernels as core_kernels  # noqa: E402
from netsim import metrics  # noqa: E402
from netsim.compiled import compiled_copy  # noqa: E402
from netsim.config import ConfigWarning  # noqa: E402
from netsim.cosim import CommandError  # noqa: E402
from netsim.envs import _kernels, coverage_v0  # noqa: E402
from netsim.errors import ConfigError  # noqa: E402
from netsim.run import collect  # noqa: E402
from tests.oracles import envs as oracle  # noqa: E402

SMALL = {"n_robots": 6, "side_m": 200.0, "range_m": 40.0, "centre_side_m": 60.0, "max_cycles": 12}


def steps(env, actions_rng, k):
    """``k`` steps of random actions from ``actions_rng``; every step's outputs."""
    out = []
    for _ in range(k):
        actions = {a: actions_rng.uniform(-2.0, 2.0, 2) for a in env.agents}
        out.append(env.step(actions))
    return out


def test_passes_pettingzoo_parallel_api_test():
    """The environment passes PettingZoo's own parallel API test."""
    parallel_api_test(coverage_v0.parallel_env(**SMALL), num_cycles=15)


def test_passes_pettingzoo_state_test():
    """state() and state_space pass PettingZoo's own state test, through the turn-based
    wrapper and in parallel."""
    from pettingzoo.test import state_test

    state_test(coverage_v0.env(**SMALL), coverage_v0.parallel_env(**SMALL), num_cycles=10)


def test_state_is_every_robots_own_observation_at_its_true_position():
    """The state is each robot's own part of its observation (position, velocity, role
    one-hot), robot after robot: the true positions, which no agent observes of another."""
    env = coverage_v0.parallel_env(**SMALL)
    with pytest.raises(RuntimeError, match=r"no episode yet: call reset\(\)"):
        env.state()
    obs, infos = env.reset(seed=4)
    rng = np.random.default_rng(4)
    for _ in range(3):
        obs, _, _, _, infos = env.step({a: rng.uniform(-2.0, 2.0, 2) for a in env.agents})
    own = 4 + len(env.role_names)
    state = env.state()
    assert state.dtype == np.float32 and env.state_space.contains(state)
    rows = state.reshape(SMALL["n_robots"], own)
    assert np.array_equal(rows, np.stack([obs[a][:own] for a in env.possible_agents]))
    assert np.allclose(rows[:, :2], infos["robot_0"]["positions_m"], atol=1e-4)
    assert rows[:, 4:].sum(axis=1).tolist() == [1.0] * SMALL["n_robots"]  # one role each
    assert not np.array_equal(rows[:, 2:4], np.zeros((SMALL["n_robots"], 2)))  # they move


def test_passes_pettingzoo_parallel_seed_test():
    """The environment passes PettingZoo's own seed test (same seed, same episode)."""
    parallel_seed_test(lambda: coverage_v0.parallel_env(**SMALL))


def test_same_seed_and_actions_give_the_same_episode():
    """Two environments reset with the same seed and given the same actions return the
    same observations, rewards and infos at every step, bit for bit."""
    runs = []
    for _ in range(2):
        env = coverage_v0.parallel_env(**SMALL)
        obs, _ = env.reset(seed=7)
        runs.append((obs, steps(env, np.random.default_rng(1), 12)))
    (obs_a, steps_a), (obs_b, steps_b) = runs
    assert all(np.array_equal(obs_a[a], obs_b[a]) for a in obs_a)
    for (oa, ra, _, ta, ia), (ob, rb, _, tb, ib) in zip(steps_a, steps_b):
        assert all(oa[a].tobytes() == ob[a].tobytes() for a in oa)
        assert ra == rb and ta == tb
        assert ia["robot_0"]["positions_m"].tobytes() == ib["robot_0"]["positions_m"].tobytes()


def test_reset_without_seed_is_a_new_episode():
    """reset() after reset(seed=s) starts another episode (the next run of the seed)."""
    env = coverage_v0.parallel_env(**SMALL)
    first, _ = env.reset(seed=3)
    second, _ = env.reset()
    again, _ = env.reset(seed=3)
    assert not np.array_equal(first["robot_0"], second["robot_0"])
    assert np.array_equal(first["robot_0"], again["robot_0"])


def test_observations_lie_in_the_observation_space():
    """Every observation of an episode is in the agent's observation space."""
    env = coverage_v0.parallel_env(**{**SMALL, "max_cycles": 30})
    obs, _ = env.reset(seed=2)
    space = env.observation_space("robot_0")
    seen = [obs] + [s[0] for s in steps(env, np.random.default_rng(4), 30)]
    assert all(space.contains(o[a]) for o in seen for a in o)


def test_observation_holds_neighbours_as_their_acks_told_them():
    """An agent's observation: its position, velocity and role, then its K nearest live
    table entries by told position, relative to it, with the age of the Ack that told it."""
    env = coverage_v0.parallel_env(**{**SMALL, "max_neighbours": 3})
    env.reset(seed=5)
    obs, *_ = env.step({a: np.array([0.5, -0.25]) for a in env.agents})
    sim = env.sim
    pos = sim.positions()
    ids, told, heard_s = sim.neighbour_view.heard(sim.now)
    for i, agent in enumerate(env.possible_agents):
        o = obs[agent].astype(float)
        np.testing.assert_allclose(o[:2], pos[i], rtol=1e-6)
        np.testing.assert_allclose(o[2:4], sim.state.velocity_mps[i], rtol=1e-6)
        assert o[4:7].tolist() == [float(k == sim.groups.role[i]) for k in range(3)]
        live = np.flatnonzero(ids[i] >= 0)
        assert sorted(ids[i][live].tolist()) == sim.neighbours(i).tolist()
        near = live[np.argsort(((told[i, live] - pos[i]) ** 2).sum(axis=1), kind="stable")][:3]
        rows = o[7:].reshape(3, 4)
        for row, slot in zip(rows, near):
            np.testing.assert_allclose(row[:2], told[i, slot] - pos[i], rtol=1e-5, atol=1e-4)
            assert row[2] == pytest.approx(sim.now - heard_s[i, slot], abs=1e-6) and row[3] == 1.0
        assert (rows[len(near) :] == 0).all()


def test_reward_is_the_coverage_gain_less_the_component_penalty():
    """reward = C(t) - C(t - step) - penalty x (components of the true network - 1), the
    same for every agent, from the team's positions."""
    params = {**SMALL, "placement": "uniform", "component_penalty": 0.05, "max_cycles": 8}
    env = coverage_v0.parallel_env(**params)
    _, infos = env.reset(seed=11)
    before = infos["robot_0"]["positions_m"]
    radius, side = params["range_m"], params["side_m"]
    split = 0
    for _, rewards, _, _, infos in steps(env, np.random.default_rng(3), 8):
        pos = infos["robot_0"]["positions_m"]
        gain = oracle.covered_fraction_grid(pos, radius, 0.0, 0.0, side, side, 100) - oracle.covered_fraction_grid(
            before, radius, 0.0, 0.0, side, side, 100
        )
        parts = int(metrics.components(pos, params["range_m"]).max() + 1)
        split += parts > 1
        assert len(set(rewards.values())) == 1
        assert rewards["robot_0"] == pytest.approx(gain - 0.05 * (parts - 1), abs=1e-12)
        before = pos
    assert split  # the penalty was at stake


def test_episode_is_truncated_after_max_cycles():
    """After max_cycles steps every agent is truncated (none terminated) and the agents are gone."""
    env = coverage_v0.parallel_env(**{**SMALL, "max_cycles": 4})
    env.reset(seed=0)
    out = steps(env, np.random.default_rng(0), 4)
    assert [all(s[3].values()) for s in out] == [False, False, False, True]
    assert not any(any(s[2].values()) for s in out)
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})


def test_infos_give_the_team_positions():
    """infos[agent]["positions_m"] is the team's (N, 2) positions at the step's end."""
    env = coverage_v0.parallel_env(**SMALL)
    env.reset(seed=1)
    _, _, _, _, infos = steps(env, np.random.default_rng(2), 3)[-1]
    assert all(np.array_equal(infos[a]["positions_m"], env.sim.positions()) for a in env.agents)
    assert env.sim.now == 3.0


@pytest.mark.parametrize(
    ("action", "named"),
    [
        (np.array([1.0, 0.0, 0.0]), r"\[1\., 0\., 0\.\]"),
        (np.array([2.5, 0.0]), r"\[2\.5, 0\.0\]"),
        (np.array([np.nan, 0.0]), "nan"),
        ("fast", "'fast'"),
        (("1", "2"), r"\('1', '2'\): must be a velocity \(vx, vy\) of numbers"),
        ((True, False), r"\(True, False\): must be a velocity \(vx, vy\) of numbers"),
    ],
)
def test_bad_action_names_it_and_changes_nothing(action, named):
    """An action of the wrong shape, outside the box or not finite raises a CommandError
    naming the agent and the value; the episode goes on as if it had not been given."""

    def play(bad: bool):
        env = coverage_v0.parallel_env(**SMALL)
        env.reset(seed=4)
        rng = np.random.default_rng(9)
        steps(env, rng, 2)
        if bad:
            actions = {a: np.array([0.1, 0.1]) for a in env.agents}
            actions["robot_3"] = action
            with pytest.raises(CommandError, match=named) as err:
                env.step(actions)
            assert "robot_3" in str(err.value)
        return steps(env, rng, 3)

    good, bad = play(False), play(True)
    for (og, rg, *_), (ob, rb, *_) in zip(good, bad):
        assert rg == rb and all(np.array_equal(og[a], ob[a]) for a in og)


def test_action_for_an_unknown_agent_is_refused():
    """An action for an agent that does not exist raises a CommandError naming it."""
    env = coverage_v0.parallel_env(**SMALL)
    env.reset(seed=0)
    with pytest.raises(CommandError, match="robot_99"):
        env.step({"robot_99": np.zeros(2)})


def test_bad_parameter_is_a_config_error():
    """A bad keyword value raises ConfigError naming the key and the value; so does an
    unknown keyword (with the keys allowed), a ``netsim`` that is not a table, a seed in
    ``netsim`` (the episodes' seeds are the environment's) and a seed that is no whole
    number."""
    with pytest.raises(ConfigError, match="coverage_v0.n_robots = 0"):
        coverage_v0.parallel_env(n_robots=0)
    with pytest.raises(ConfigError, match="render_mode = 'ansi': must be None, 'human' or 'rgb_array'"):
        coverage_v0.parallel_env(render_mode="ansi")
    with pytest.raises(
        ConfigError, match=r"n_robot = 4: unknown key \(did you mean 'n_robots'\?\); allowed: .*n_robots"
    ):
        coverage_v0.parallel_env(n_robot=4)
    with pytest.raises(ConfigError, match=r"netsim = \[1\]: must be a table"):
        coverage_v0.parallel_env(**SMALL, netsim=[1])
    with pytest.raises(ConfigError, match="seed = 5: the environment's"):
        coverage_v0.parallel_env(**SMALL, netsim={"seed": 5})
    env = coverage_v0.parallel_env(**SMALL)
    for seed in (1.5, "3", True):
        with pytest.raises(ConfigError, match="seed = .*: must be a whole number"):
            env.reset(seed=seed)


def test_keywords_take_numpy_numbers_and_the_unknown_key_lists_every_keyword():
    """A keyword given as a numpy number (a sweep's array element) is the Python number it
    holds; an unknown keyword's message lists every documented keyword, ``netsim`` and
    ``render_mode`` among them; a negative seed is refused when the environment is made."""
    env = coverage_v0.parallel_env(n_robots=np.int64(4), step_s=np.float32(0.5), seed=np.int64(3))
    assert (env.params.n_robots, env.params.step_s, env.params.seed) == (4, 0.5, 3)
    assert type(env.params.n_robots) is int and type(env.params.step_s) is float
    with pytest.raises(ConfigError, match="allowed: .*netsim.*render_mode"):
        coverage_v0.parallel_env(n_robot=4)
    with pytest.raises(ConfigError, match="seed = -1: must be >= 0"):
        coverage_v0.parallel_env(seed=-1)


@pytest.mark.parametrize("netsim", [None, {"world": {"placement": "middle"}}])
def test_a_placement_that_names_nothing_is_refused_when_the_environment_is_made(netsim):
    """A ``placement`` that is no placement's name and no CSV file is refused by
    ``parallel_env`` itself (given as the keyword or through ``netsim``), not at reset."""
    keywords = {"placement": "middle"} if netsim is None else {"netsim": netsim}
    with pytest.raises(ConfigError, match="world.placement = 'middle': must be"):
        coverage_v0.parallel_env(**SMALL, **keywords)


def test_actions_that_are_not_a_dict_are_refused_in_one_line():
    """Actions given as an array (one row per agent) instead of a dict raise a CommandError
    that says what the actions must be, not numpy's truth-value error."""
    env = coverage_v0.parallel_env(**SMALL)
    env.reset(seed=0)
    with pytest.raises(CommandError, match="actions must be a dict from agent name to velocity"):
        env.step(np.zeros((SMALL["n_robots"], 2), np.float32))


@pytest.mark.parametrize("action", [np.array([9.0, 0.0], np.float32), np.zeros(3, np.float32), None])
def test_a_bad_action_in_turns_raises_when_given_and_the_agent_gives_another(action):
    """In the AEC API a bad action raises at the agent's own step and is not kept: the same
    agent then gives a good one and the episode goes on as if the bad one had not been given
    (the plain conversion kept it, and every later step raised)."""

    def play(bad: bool):
        env = coverage_v0.env(**SMALL)
        env.reset(seed=4)
        rng = np.random.default_rng(9)
        out = []
        for k in range(3 * SMALL["n_robots"]):
            if bad and k == 1:
                with pytest.raises(CommandError, match="robot_1"):
                    env.step(action)
                assert env.agent_selection == "robot_1"
            env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            out.append(env.last()[:2])
        return out

    good, bad = play(False), play(True)
    assert all(np.array_equal(og, ob) and rg == rb for (og, rg), (ob, rb) in zip(good, bad))


def test_render_without_a_render_mode_warns():
    """render() of an environment made without render_mode draws nothing and says why."""
    env = coverage_v0.parallel_env(**SMALL)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode='rgb_array'"):
        assert env.render() is None


def test_human_render_mode_where_the_asked_backend_cannot_start_says_there_is_no_display(monkeypatch):
    """MPLBACKEND asks for a window's backend on a machine with no display: matplotlib falls
    back to Agg, and the warning says so, naming the backend asked for and the display (it
    told the user to set MPLBACKEND, which they had), at the user's own reset() line."""
    from netsim.envs import drawing

    monkeypatch.setenv("MPLBACKEND", "TkAgg")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(drawing, "matplotlib_backend", lambda: "agg")
    env = coverage_v0.parallel_env(**SMALL, render_mode="human")
    with pytest.warns(UserWarning) as said:
        env.reset(seed=0)
    (w,) = [w for w in said if "shows a window" in str(w.message)]
    assert "could not start the backend MPLBACKEND asks for (TkAgg): this machine has no display" in str(w.message)
    assert "fell back to agg" in str(w.message) and w.filename == __file__


def test_human_render_mode_without_a_window_says_so_once(monkeypatch):
    """render_mode = "human" where matplotlib draws no window (Agg, as on a server): one
    warning naming the backend and what to do, for the environment's life; render() returns
    None, and reset() and step() go on."""
    monkeypatch.setattr(coverage_v0, "shows_windows", lambda: False)
    env = coverage_v0.parallel_env(**SMALL, render_mode="human")
    with pytest.warns(UserWarning, match="render_mode='human' shows a window.*MPLBACKEND") as said:
        env.reset(seed=0)
        env.step({a: np.zeros(2, np.float32) for a in env.agents})
        assert env.render() is None
    assert len([w for w in said if "shows a window" in str(w.message)]) == 1


def test_human_render_mode_shows_each_step_in_one_window(monkeypatch):
    """render_mode = "human" with a window's backend: reset() and every step() show the
    frame render_mode = "rgb_array" returns at the same instant, in one window of the
    environment's own (another environment opens another), reopened only when the user
    closed it, closed by close()."""
    import matplotlib.pyplot as plt

    monkeypatch.setattr(coverage_v0, "shows_windows", lambda: True)
    opened: list[bool] = []
    monkeypatch.setattr(plt, "show", lambda block=None: opened.append(block is False))
    # The window's wait between frames (real time) is not this test's: no waiting.
    monkeypatch.setattr(FigureCanvasBase, "start_event_loop", lambda self, timeout=0: None)
    plt.close("all")

    def window() -> np.ndarray:
        (number,) = plt.get_fignums()
        return np.asarray(plt.figure(number).axes[0].images[0].get_array())

    human = coverage_v0.parallel_env(**SMALL, render_mode="human")
    frames = coverage_v0.parallel_env(**SMALL, render_mode="rgb_array")
    human.reset(seed=2)
    frames.reset(seed=2)
    shown, expected = [window().copy()], [frames.render()]
    for k in range(2):
        for env in (human, frames):
            env.step({a: np.full(2, 0.5 - k, np.float32) for a in env.agents})
        shown.append(window().copy())
        expected.append(frames.render())
    assert opened == [True]
    assert len(shown) == 3
    assert all(np.array_equal(s, e) for s, e in zip(shown, expected))
    assert not np.array_equal(shown[0], shown[2])  # the team moved
    assert human.render() is None
    plt.close("all")  # the user closes the window: the next frame opens another
    human.step({a: np.zeros(2, np.float32) for a in human.agents})
    assert len(plt.get_fignums()) == 1 and opened == [True, True]
    other = coverage_v0.parallel_env(**SMALL, render_mode="human")
    other.reset(seed=3)
    assert len(plt.get_fignums()) == 2
    human.close()
    other.close()
    assert plt.get_fignums() == []


def test_a_window_keeps_each_frame_on_screen_for_one_frame_time(monkeypatch):
    """A window shows a frame no sooner than ``1 / fps`` after the last one (the wait runs
    the window's event loop, so it answers meanwhile); a frame that comes later than that
    shows at once, and so does the first."""
    import matplotlib.pyplot as plt

    from netsim.envs.drawing import Window

    now = [0.0]
    waits: list[float] = []

    def event_loop(self, timeout=0):
        waits.append(timeout)
        now[0] += timeout

    monkeypatch.setattr(FigureCanvasBase, "start_event_loop", event_loop)
    monkeypatch.setattr(plt, "show", lambda block=None: None)
    window = Window(clock=lambda: now[0])
    image = np.zeros((20, 30, 3), np.uint8)
    window.show(image, 2.0)
    drawn = list(waits)
    now[0] += 0.1
    window.show(image, 2.0)  # 0.1 s after the first: waits the 0.4 s left
    assert waits[len(drawn)] == pytest.approx(0.4)
    shown = len(waits)
    now[0] += 3.0
    window.show(image, 2.0)  # later than a frame's time: no wait
    assert waits[shown:] == drawn
    shown = len(waits)
    window.show(image, 0.0)  # no pacing asked: no wait (and no division by zero)
    assert waits[shown:] == drawn
    window.close()


@pytest.fixture
def paces(monkeypatch) -> list[float]:
    """The frame rates the environment's window is asked to keep, frame by frame (a window
    that records them in place of drawing)."""
    asked: list[float] = []

    class Recorded:
        def show(self, image, fps):
            asked.append(fps)

        def close(self):
            pass

    monkeypatch.setattr(coverage_v0, "shows_windows", lambda: True)
    monkeypatch.setattr(coverage_v0, "Window", Recorded)
    return asked


def test_the_window_shows_the_team_in_real_time(paces):
    """render_fps is a step per step_s (real time), in the environment's metadata, and the
    window paces its frames by it, also once the user changed it there."""
    env = coverage_v0.parallel_env(**SMALL, step_s=0.5, render_mode="human")
    assert env.metadata["render_fps"] == 2.0
    assert coverage_v0.parallel_env(**SMALL).metadata["render_fps"] == 1.0  # another's own
    env.reset(seed=0)
    env.metadata["render_fps"] = 10
    env.step({a: np.zeros(2, np.float32) for a in env.agents})
    env.metadata["render_fps"] = None  # Gymnasium's "not declared": no wait
    env.step({a: np.zeros(2, np.float32) for a in env.agents})
    assert paces == [2.0, 10.0, 0.0]
    env.close()


def test_the_turns_window_is_paced_by_the_turns_render_fps(paces):
    """In the AEC API (env()) too, a render_fps set in env.metadata paces the window (the
    conversion to turns kept a copy of the table, which the window never read)."""
    env = coverage_v0.env(**SMALL, step_s=0.5, render_mode="human")
    assert env.metadata["render_fps"] == 2.0
    env.reset(seed=0)
    env.metadata["render_fps"] = 10
    for agent in env.agents[:]:
        assert env.agent_selection == agent
        env.step(np.zeros(2, np.float32))
    assert paces == [2.0, 10.0]
    env.close()


@pytest.mark.parametrize(
    ("backend", "window"),
    [
        ("agg", False),
        ("pdf", False),
        ("module://matplotlib_inline.backend_inline", False),
        ("TkAgg", True),
        ("QtAgg", True),
    ],
)
def test_a_window_is_shown_only_by_a_backend_that_has_one(monkeypatch, backend, window):
    """Whether render_mode = "human" can show a window: matplotlib's interactive backends
    (any case) have one, the ones that draw to a file or a buffer do not, nor Jupyter's
    inline backend (a picture printed a frame)."""
    from netsim.envs import drawing

    monkeypatch.setattr(drawing, "matplotlib_backend", lambda: backend)
    assert drawing.shows_windows() is window


def test_passes_pettingzoo_render_test(monkeypatch):
    """PettingZoo's render_test, which makes the environment in every mode it lists
    ("human" included) and checks what render() returns in each."""
    from pettingzoo.test import render_test

    monkeypatch.setattr(coverage_v0, "shows_windows", lambda: False)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "render_mode='human' shows a window", UserWarning)
        render_test(lambda render_mode: coverage_v0.env(**SMALL, render_mode=render_mode))


def test_the_link_quality_recipe_warns_of_nothing(recwarn):
    """The documented way to offer link quality (a log-distance radio in ``netsim``) warns
    of no setting the user did not make (the unit disk's range is not passed to it)."""
    env = coverage_v0.parallel_env(n_robots=4, max_cycles=3, link_quality=True, netsim=LOG_DISTANCE)
    env.reset(seed=1)
    assert [str(w.message) for w in recwarn] == []


@pytest.mark.slow
def test_render_draws_an_rgb_frame():
    """render_mode = "rgb_array": render() returns an (H, W, 3) uint8 image of the team."""
    env = coverage_v0.parallel_env(**SMALL, render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 10
    with pytest.warns(UserWarning, match="render_mode"):
        assert coverage_v0.parallel_env(**SMALL).render() is None


@pytest.mark.parametrize("compiled", [False, True], ids=["plain", "compiled"])
def test_measure_kernels_equal_the_numpy_oracles(compiled):
    """The covered fraction, component count, nearest told neighbours and strongest heard
    ones (link quality) of the kernels, plain and compiled, are the numpy oracles' exactly
    (including disks past the border, and areas off the origin)."""
    kernels = compiled_copy("netsim.envs._kernels") if compiled else _kernels
    core = compiled_copy("netsim._kernels") if compiled else core_kernels
    rng = np.random.default_rng(0)
    for n in (1, 5, 30):
        pos = rng.uniform(-20.0, 220.0, (n, 2))
        for area in ((0.0, 0.0, 200.0, 200.0), (-15.0, 30.0, 180.0, 120.0)):
            assert kernels.covered_fraction_grid(pos, 35.0, *area, 64) == oracle.covered_fraction_grid(
                pos, 35.0, *area, 64
            )
        a, b = rng.integers(0, n, (2, n))
        assert core.component_count(n, a, b) == oracle.component_count(n, a, b)
        slots = 8
        ids = np.where(rng.random((n, slots)) < 0.6, rng.integers(0, n, (n, slots)), -1)
        told = rng.uniform(0.0, 200.0, (n, slots, 2))
        told[:, 1] = told[:, 0]  # ties: the lower slot first
        heard = rng.uniform(0.0, 3.0, (n, slots))
        for k in (0, 3, 10):
            a, b = np.zeros((n, 40), np.float32), np.zeros((n, 40), np.float32)
            kernels.nearest_told(a, 2, pos, ids, told, heard, 3.5, k, 3.0)
            oracle.nearest_told(b, 2, pos, ids, told, heard, 3.5, k, 3.0)
            assert a.tobytes() == b.tobytes()
        power = np.where(rng.random((n, slots)) < 0.9, rng.uniform(-85.0, -30.0, (n, slots)), np.nan)
        power[:, 2] = power[:, 3]  # ties: the lower slot first
        for k in (0, 3, 10):
            a, b = np.zeros((n, 40), np.float32), np.zeros((n, 40), np.float32)
            kernels.strongest_heard(a, 2, ids, power, heard, 3.5, k, -80.0, -35.0, 3.0)
            oracle.strongest_heard(b, 2, ids, power, heard, 3.5, k, -80.0, -35.0, 3.0)
            assert a.tobytes() == b.tobytes()


def test_covered_fraction_grid_is_the_search_trees():
    """The grid's covered fraction is netsim.metrics.covered_fraction's on the same grid."""
    from netsim.metrics import covered_fraction

    pos = np.random.default_rng(1).uniform(0.0, 100.0, (12, 2))
    assert (
        oracle.covered_fraction_grid(pos, 9.0, 0.0, 0.0, 100.0, 100.0, 80) == covered_fraction(pos, 9.0, 100.0, 80)[0]
    )


def test_component_count_is_that_of_the_links():
    """The component count of a set of links is netsim.metrics.components_of_links's, and
    netsim.metrics.component_count's (none of no robot)."""
    rng = np.random.default_rng(2)
    for n in (1, 7, 40):
        a, b = rng.integers(0, n, (2, n // 2 + 1))
        assert oracle.component_count(n, a, b) == metrics.components_of_links(n, a, b).max() + 1
        assert metrics.component_count(n, a, b) == oracle.component_count(n, a, b)
    assert metrics.component_count(0, np.empty(0, np.int64), np.empty(0, np.int64)) == 0


@pytest.mark.slow
def test_learn_coverage_example_runs_and_writes_csv_and_png(tmp_path):
    """experiments/learn_coverage.py runs both policies, prints the covered fraction of the
    bound each reaches, and writes its CSV and PNG."""
    import subprocess
    import sys
    from pathlib import Path

    import pandas as pd

    script = Path(__file__).resolve().parents[1] / "experiments" / "learn_coverage.py"
    args = ["--n", "6", "--cycles", "6", "--episodes", "1", "--out", str(tmp_path)]
    run = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "covered_of_bound" in run.stdout and "forces" in run.stdout and "random" in run.stdout
    table = pd.read_csv(tmp_path / "learn_coverage.csv")
    assert sorted(table["policy"]) == ["forces", "random"]
    assert (table["covered_of_bound"] > 0).all()
    assert (tmp_path / "learn_coverage.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
@pytest.mark.parametrize("args", [["--episodes", "0"], ["--n", "0"]])
def test_learn_coverage_bad_input_is_one_line_exit_2_nothing_written(tmp_path, args):
    """A bad option of the example: exit status 2, one line on stderr, nothing written."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "experiments" / "learn_coverage.py"
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, str(script), *args, "--out", str(out)], capture_output=True, text=True)
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert args[1] in run.stderr
    assert not out.exists()


def test_extra_configuration_reaches_the_runs_and_is_checked_at_once():
    """``netsim`` adds keys to every episode's configuration; a bad one is a ConfigError
    when the environment is made."""
    env = coverage_v0.parallel_env(**SMALL, netsim={"channel": {"loss_model": "bernoulli", "loss_probability": 0.25}})
    env.reset(seed=0)
    assert env.sim.config.channel.loss_probability == 0.25
    with pytest.raises(ConfigError, match="channel.loss_probabilty"):
        coverage_v0.parallel_env(**SMALL, netsim={"channel": {"loss_probabilty": 0.25}})


# -- the environment measures the run it has (whatever ``netsim`` sets) -------------------
def episode(env, seed: int) -> list[tuple[dict, dict, float]]:
    """A whole episode of random actions: ``(observations, infos, t_s)`` at the reset and
    after every step."""
    obs, infos = env.reset(seed=seed)
    out = [(obs, infos, env.sim.now)]
    rng = np.random.default_rng(seed)
    while env.agents:
        obs, _, _, _, infos = env.step({a: rng.uniform(-2.0, 2.0, 2) for a in env.agents})
        out.append((obs, infos, env.sim.now))
    return out


def links_components(env, seen) -> tuple[list, list]:
    """The components the environment gave at each of ``seen``'s instants, and those of the
    episode's links table (links.parquet) at the same instants."""
    links = collect(env.sim)["links"]
    expected = metrics.components_in_links_table(links, env.sim.state.n, [t for *_, t in seen])
    return [infos["robot_0"]["components"] for _, infos, _ in seen], expected.tolist()


def test_components_and_disks_follow_a_range_set_in_netsim():
    """With channel.range_m set through ``netsim``, the reward's components are those of
    the links of that range (links.parquet's at each step's end) and the coverage disks
    have that radius."""
    env = coverage_v0.parallel_env(**{**SMALL, "placement": "uniform"}, netsim={"channel": {"range_m": 80.0}})
    seen = episode(env, 3)
    for _, infos, _ in seen:
        pos = infos["robot_0"]["positions_m"]
        assert infos["robot_0"]["covered_fraction"] == oracle.covered_fraction_grid(
            pos, 80.0, 0.0, 0.0, 200.0, 200.0, 100
        )
    got, expected = links_components(env, seen)
    assert got == expected
    assert max(got) > 1  # a split team was seen


@pytest.mark.parametrize(
    ("placement", "netsim"),
    [
        ("uniform", {"channel": {"propagation": "log_distance", "shadowing_sigma_db": 6.0, "path_loss_exponent": 4.0}}),
        ("centre", {"world": {"map": "office", "bounds_m": "map"}}),
    ],
    ids=["shadowing", "walls"],
)
def test_components_under_shadowing_or_walls_are_those_of_the_links_table(placement, netsim):
    """Under shadowing, or on a map, the reward's components are those of the links the
    channel makes, the links of links.parquet at the reset and at each step's end."""
    keywords = {**SMALL, "placement": placement}
    if "channel" in netsim:
        del keywords["range_m"]  # the radio's law implies the range: SMALL's would be ignored
    env = coverage_v0.parallel_env(**keywords, netsim=netsim)
    got, expected = links_components(env, episode(env, 1))
    assert got == expected
    assert max(got) > 1  # a split team was seen


@pytest.mark.parametrize(
    ("world", "area"),
    [
        ({"side_m": 800.0}, (0.0, 0.0, 800.0, 800.0)),
        ({"bounds_m": [100.0, -50.0, 500.0, 250.0]}, (100.0, -50.0, 400.0, 300.0)),
    ],
)
def test_area_set_in_netsim_bounds_observations_and_coverage(world, area):
    """With the area set through ``netsim`` (world.side_m, world.bounds_m), every
    observation lies in the observation space and the covered fraction is that of the run's
    area."""
    env = coverage_v0.parallel_env(**{**SMALL, "placement": "uniform"}, netsim={"world": world})
    space = env.observation_space("robot_0")
    for obs, infos, _ in episode(env, 4):
        assert all(space.contains(o) for o in obs.values())
        pos = infos["robot_0"]["positions_m"]
        assert infos["robot_0"]["covered_fraction"] == oracle.covered_fraction_grid(pos, 40.0, *area, 100)
    x0, y0, w, h = area
    assert space.low[:2].tolist() == [x0, y0] and space.high[:2].tolist() == [x0 + w, y0 + h]


def test_tau_set_in_netsim_bounds_the_ages_observed():
    """With protocol.tau_s set through ``netsim`` the ages observed are bounded by it, and
    every observation lies in the observation space."""
    env = coverage_v0.parallel_env(**{**SMALL, "placement": "uniform"}, netsim={"protocol": {"tau_s": 6.0}})
    space = env.observation_space("robot_0")
    ages = space.high[7 + 2 :: 4]
    assert (ages == 6.0).all()
    old = 0
    for obs, _, _ in episode(env, 5):
        assert all(space.contains(o) for o in obs.values())
        old += sum(int((o[7 + 2 :: 4] > 3.0).sum()) for o in obs.values())
    assert old  # ages beyond 3 ack periods were seen


@pytest.mark.parametrize(
    ("netsim", "key"),
    [
        ({"world": {"n_robots": 7}}, "world.n_robots = 7"),
        ({"mobility": {"model": "random_waypoint"}}, "mobility.model = 'random_waypoint'"),
        ({"duration_s": 5.0}, "duration_s = 5.0"),
        (
            {"events": {"runtime_links": "off"}, "channel": {"propagation": "log_distance", "shadowing_sigma_db": 6.0}},
            "events.runtime_links = 'off'",
        ),
        ({"world": {"torus": True}}, "world.torus = true"),
        ({"protocol": {"model": "aodv"}}, "protocol.model = 'aodv'"),
        ({"protocol": {"model": "none"}}, "protocol.model = 'none'"),
        ({"protocol": {"model": "ack"}}, "protocol.model = 'ack'"),
    ],
)
def test_setting_the_environment_cannot_honour_is_refused(netsim, key):
    """A setting of ``netsim`` the environment cannot honour (another number of robots,
    robots moved by a model, another duration, no link events under shadowing, a torus) raises a
    one-line ConfigError naming it when the environment is made, and nothing else is said
    (no warning of the keys that setting leaves unused: the protocol's Ack keys)."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        with pytest.raises(ConfigError, match=key.replace("(", r"\(")) as err:
            coverage_v0.parallel_env(**SMALL, netsim=netsim)
    assert "\n" not in str(err.value)
    assert [str(w.message) for w in said] == []


def test_a_key_ignored_is_said_once_for_the_environment_not_at_every_reset():
    """A key of ``netsim`` that the run does not use is warned of when the environment is
    made, once; the resets, which build the same configuration, say nothing more."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        env = coverage_v0.parallel_env(**SMALL, netsim={"mobility": {"speed_max_mps": 3.0}})
        env.reset(seed=1)
        env.reset()
    told = [str(w.message) for w in said if issubclass(w.category, ConfigWarning)]
    assert len(told) == 1 and told[0].startswith("mobility.speed_max_mps: not used by 'external'")


def test_step_without_actions_keeps_every_velocity():
    """env.step({}) is a step in which every robot keeps the velocity it had."""
    env = coverage_v0.parallel_env(**SMALL)
    env.reset(seed=6)
    steps(env, np.random.default_rng(8), 1)
    before = env.sim.state.velocity_mps.copy()
    pos = env.sim.positions()
    env.step({})
    assert np.array_equal(env.sim.state.velocity_mps, before) and (before != 0).any()
    moving = (env.sim.state.velocity_mps != 0).any(axis=1)
    assert (env.sim.positions()[moving] != pos[moving]).any(axis=1).all()


def test_a_duration_that_no_longer_matches_max_cycles_is_refused_at_reset():
    """A duration set through ``netsim`` that matched ``max_cycles`` when the environment
    was made, and no longer does once ``max_cycles`` is changed (as PettingZoo's tests do),
    is refused at the next reset in one line, not by a run stopped mid-episode."""
    step_s = SMALL.get("step_s", 1.0)
    max_cycles = SMALL.get("max_cycles", 200)
    env = coverage_v0.parallel_env(**SMALL, netsim={"duration_s": max_cycles * step_s})
    env.max_cycles = max_cycles + 5
    with pytest.raises(ConfigError, match="duration_s") as err:
        env.reset(seed=1)
    assert "\n" not in str(err.value)


LOG_DISTANCE = {"channel": {"propagation": "log_distance", "shadowing_sigma_db": 4.0}}


@pytest.mark.parametrize("k", [4, 20])
def test_link_quality_observes_the_strongest_live_neighbours_at_the_documented_index(k):
    """With link_quality, an agent's observation holds from index 7 + 4K on its K strongest
    live entries of sim.link_quality (power dBm, age s, 1), strongest first, padded with
    (sensitivity, 0, 0), inside the observation space; the fields before are unchanged.
    K past the neighbour table's first 16 slots is padded alike (it was left 0 dBm, outside
    the space)."""
    env = coverage_v0.parallel_env(n_robots=8, max_cycles=6, max_neighbours=k, link_quality=True, netsim=LOG_DISTANCE)
    plain = coverage_v0.parallel_env(n_robots=8, max_cycles=6, max_neighbours=k, netsim=LOG_DISTANCE)
    start = 7 + 4 * k
    assert env.link_quality_start == start
    assert env.observation_space("robot_0").shape == (start + 3 * k,)
    seen = padded = 0
    obs, _ = env.reset(seed=3)
    plain_obs, _ = plain.reset(seed=3)
    for _ in range(6):
        for a, o in obs.items():
            assert env.observation_space(a).contains(o)
            assert o[:start].tobytes() == plain_obs[a].tobytes()
            lq = env.sim.link_quality(int(a.split("_")[1]))
            top = lq.sort_values("rx_power_dbm", ascending=False, kind="stable").head(k)
            got = o[start:].reshape(k, 3)
            m = len(top)
            assert got[:m, 0].tolist() == top["rx_power_dbm"].to_numpy(np.float32).tolist()
            assert got[:m, 1].tolist() == top["age_s"].to_numpy(np.float32).tolist()
            assert (got[:m, 2] == 1).all()
            assert got[m:].tolist() == [[-80.0, 0.0, 0.0]] * (k - m)
            seen += m
            padded += k - m
        actions = {a: env.action_space(a).sample() for a in env.agents}
        obs, *_ = env.step(actions)
        plain_obs, *_ = plain.step(actions)
    assert seen > 20 and padded > 0


def test_link_quality_without_a_power_is_refused():
    """link_quality under the unit disk (no power measured) is a one-line ConfigError."""
    with pytest.raises(ConfigError, match="link_quality") as err:
        coverage_v0.parallel_env(n_robots=4, link_quality=True)
    assert "\n" not in str(err.value)


def test_a_refused_reset_leaves_the_environment_as_it_was():
    """reset(seed=-1) is refused; the next reset() is the next episode of the seed given
    before, as if the refused call had not been made."""
    env = coverage_v0.parallel_env(n_robots=6, max_cycles=5)
    env.reset(seed=3)
    with pytest.raises(ConfigError, match="seed = -1"):
        env.reset(seed=-1)
    obs, _ = env.reset()
    again = coverage_v0.parallel_env(n_robots=6, max_cycles=5)
    again.reset(seed=3)
    expected, _ = again.reset()
    assert all(np.array_equal(obs[a], expected[a]) for a in obs)


def test_a_reset_builds_the_configuration_once(monkeypatch):
    """Whether the channel's law implies the ranges is read once, at construction: every
    later reset builds its episode's configuration once, not twice."""
    import netsim.config as cfgmod
    from netsim.envs.coverage_v0 import parallel_env

    env = parallel_env(netsim={"channel": {"propagation": "log_distance"}})
    built = []
    real = cfgmod.from_dict
    monkeypatch.setattr(cfgmod, "from_dict", lambda *a, **k: built.append(1) or real(*a, **k))
    env.reset(seed=1)
    env.reset(seed=2)
    assert len(built) == 2


def test_a_range_the_radio_overrides_is_said_to_be_ignored():
    """range_m given with a log-distance radio in ``netsim``, whose law implies the range:
    a ConfigWarning says it is ignored (it was dropped unsaid), and the range is the radio's."""
    with pytest.warns(ConfigWarning, match="range_m = 30: not used"):
        env = coverage_v0.parallel_env(
            **{**SMALL, "range_m": 30.0}, netsim={"channel": {"propagation": "log_distance"}}
        )
    assert env.range_m != 30.0


@pytest.mark.parametrize("speed_max_mps", [0.7, 0.1])
def test_an_action_at_the_speed_bound_is_taken_in_either_precision(speed_max_mps):
    """An action whose component is the bound, as speed_max_mps (0.7: float32 rounds the
    action space's bound below it) or as the action space's float32 bound (0.1: rounded
    above it), is taken, and the robot moves at speed_max_mps; beyond both it is refused."""
    env = coverage_v0.parallel_env(**{**SMALL, "speed_max_mps": speed_max_mps})
    env.reset(seed=3)
    high = float(env.action_space("robot_0").high[0])
    assert high != speed_max_mps
    env.step({"robot_0": (speed_max_mps, 0.0), "robot_1": (0.0, -high)})
    assert env.sim.state.velocity_mps[0, 0] == speed_max_mps
    assert env.sim.state.velocity_mps[1, 1] == -min(high, speed_max_mps)
    beyond = np.nextafter(max(high, speed_max_mps), np.inf)
    with pytest.raises(CommandError, match="must be finite and within"):
        env.step({"robot_0": (beyond, 0.0)})


def test_a_warning_not_of_the_configuration_goes_on_as_it_came(monkeypatch):
    """Only the configuration's own warnings are held back until the setting is known to be
    good; any other warning raised while the runs' configuration is made goes on at once,
    from where it was raised."""
    real = coverage_v0.CoverageEnv._config

    def noisy(self, seed):
        warnings.warn("a library's own warning", DeprecationWarning, stacklevel=1)
        return real(self, seed)

    monkeypatch.setattr(coverage_v0.CoverageEnv, "_config", noisy)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        coverage_v0.parallel_env(**SMALL)
    others = [w for w in said if w.category is DeprecationWarning]
    assert [str(w.message) for w in others] == ["a library's own warning"]
    assert others[0].filename == __file__


def test_the_netsim_tables_area_holds_the_default_central_square(tmp_path):
    """An area set through ``netsim=`` (a side, bounds, a map's extent) smaller than the
    default central square (100 m) holds it, as the keyword ``side_m`` does, rather than
    refuse a centre_side_m the user never set."""
    from netsim.world.maps import save_map

    occupied = np.zeros((60, 60), dtype=bool)
    small_map = save_map(tmp_path / "small.yaml", occupied, ~occupied, 1.0)
    for world in ({"side_m": 50}, {"bounds_m": [0, 0, 60, 60]}, {"map": str(small_map), "bounds_m": "map"}):
        env = coverage_v0.parallel_env(n_robots=4, max_cycles=2, netsim={"world": world})
        env.reset(seed=0)
        assert env.sim.config.world.centre_side_m == min(env.area.width, env.area.height)
    env = coverage_v0.parallel_env(n_robots=4, max_cycles=2, netsim={"world": {"side_m": 50, "centre_side_m": 20}})
    env.reset(seed=0)
    assert env.sim.config.world.centre_side_m == 20.0


def test_a_relative_placement_file_is_found_at_every_reset(tmp_path, monkeypatch):
    """A CSV placement given relative to the working directory is the one every episode
    reads, wherever the working directory is when it starts (keyword or ``netsim=``)."""
    (tmp_path / "three.csv").write_text("x_m,y_m\n10,10\n20,20\n30,30\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for kwargs in ({"placement": "three.csv"}, {"netsim": {"world": {"placement": "three.csv"}}}):
        monkeypatch.chdir(tmp_path)
        env = coverage_v0.parallel_env(n_robots=3, max_cycles=2, **kwargs)
        env.reset(seed=0)
        monkeypatch.chdir(elsewhere)
        env.reset(seed=0)
        assert env.sim.positions().tolist() == [[10.0, 10.0], [20.0, 20.0], [30.0, 30.0]]


def test_each_agent_has_an_info_dict_of_its_own():
    """One dict was handed to every agent: a training loop that wrote into one agent's
    info wrote into all."""
    env = coverage_v0.parallel_env(**SMALL)
    _, infos = env.reset(seed=3)
    first, second = env.agents[:2]
    infos[first]["note"] = 1
    assert "note" not in infos[second]
    _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    infos[first]["note"] = 1
    assert "note" not in infos[second]


# -- rules a mutation audit found no test for ------------------------------------------------
def test_a_neighbours_offsets_are_bounded_by_the_areas_width_and_height():
    env = coverage_v0.parallel_env(
        **{**SMALL, "placement": "uniform"}, netsim={"world": {"bounds_m": [100.0, -50.0, 500.0, 250.0]}}
    )
    space = env.observation_space("robot_0")
    k = env.params.max_neighbours
    offsets_low = space.low[7 : 7 + 4 * k].reshape(k, 4)[:, :2]
    offsets_high = space.high[7 : 7 + 4 * k].reshape(k, 4)[:, :2]
    assert offsets_low.tolist() == [[-400.0, -300.0]] * k and offsets_high.tolist() == [[400.0, 300.0]] * k


def test_the_strongest_power_observable_allows_for_the_strongest_shadowing():
    """A shadowed Ack at the reference distance can arrive up to the truncation's sigmas
    above the path loss's power: the observation space holds it."""

    def highest(sigma_db):
        netsim = {"channel": {"propagation": "log_distance", "shadowing_sigma_db": sigma_db}}
        env = coverage_v0.parallel_env(n_robots=4, max_neighbours=2, link_quality=True, netsim=netsim)
        return float(env.observation_space("robot_0").high[env.link_quality_start])

    assert highest(4.0) - highest(0.0) == pytest.approx(coverage_v0.TRUNCATION_SIGMAS * 4.0)


def test_a_controller_set_in_netsim_is_refused_naming_the_key_that_set_it():
    key = "control.controllers = 'log_separation'"
    with pytest.raises(ConfigError, match=f"^{key}: the environment's agents move the robots: no controller may$"):
        coverage_v0.parallel_env(**SMALL, netsim={"control": {"controllers": ["log_separation"]}})


def test_in_turns_an_agent_whose_episode_is_over_steps_with_none():
    """PettingZoo's convention: a truncated agent's last step carries no action."""
    env = coverage_v0.env(**{**SMALL, "max_cycles": 1})
    env.reset(seed=0)
    for _ in range(SMALL["n_robots"]):
        env.step(np.zeros(2, np.float32))
    assert all(env.truncations.values())
    while env.agents:
        env.step(None)


@pytest.mark.parametrize("library", ["gymnasium", "pettingzoo"])
def test_the_environment_without_the_rl_extra_says_how_to_install_it(monkeypatch, library):
    """Without a library of the extra `rl`, importing the environment says which library and
    the install line, as the live commands say theirs."""
    import importlib
    import sys

    monkeypatch.delitem(sys.modules, "netsim.envs.coverage_v0")
    monkeypatch.setitem(sys.modules, library, None)
    with pytest.raises(ModuleNotFoundError) as err:
        importlib.import_module("netsim.envs.coverage_v0")
    assert str(err.value) == (
        f"netsim.envs needs {library}, of the optional extra 'rl': pip install 'netsim-robots[rl]' "
        "(in a clone: pip install -e '.[rl]')"
    )
