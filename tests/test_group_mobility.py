"""Gauss-Markov and reference point group mobility: each rule of the two models."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import simpy
from netsim.mobility.gauss_markov import GaussMarkovParams, _clamped_legs, gauss_markov_robot
from netsim.mobility.rpgm import MAX_DRAWS, OffsetLaw, RpgmParams, draw_offset, groups, member_offset

from netsim import load
from netsim.errors import ConfigError
from netsim.run import build, collect
from netsim.state import RobotState


def _run(settings: list[str]) -> dict[str, pd.DataFrame]:
    sim = build(load(None, ["protocol.model=none", "output.position_interval_s=0", *settings]))
    sim.run()
    return collect(sim)


def _positions_at_leg_ends(legs: pd.DataFrame, t_end: float) -> np.ndarray:
    """Every robot's position at the start and the end of each of its legs."""
    legs = legs.sort_values(["robot", "t_s"], kind="stable")
    nxt = legs.groupby("robot")["t_s"].shift(-1).fillna(t_end).to_numpy()
    dt = nxt - legs["t_s"].to_numpy()
    start = legs[["x_m", "y_m"]].to_numpy()
    end = start + legs[["vx_mps", "vy_mps"]].to_numpy() * dt[:, None]
    return np.concatenate([start, end])


class _Fixed:
    """A stand-in random generator: uniform draws give ``u``, normal draws zeros."""

    def __init__(self, u: float):
        self.u = u

    def uniform(self, lo, hi, size=None):
        return self.u

    def standard_normal(self, size):
        return np.zeros(size)


def _one_robot(p0, u: float, params: GaussMarkovParams, until_s: float, side_m: float = 100.0) -> pd.DataFrame:
    env = simpy.Environment()
    st = RobotState(1, side_m, 10.0)
    st.place(np.array([p0], dtype=float))
    env.process(gauss_markov_robot(env, st, params, side_m, 0, _Fixed(u)))
    env.run(until=until_s)
    return st.legs()


def test_gauss_markov_alpha_one_is_a_straight_line_at_the_mean_velocity():
    """With alpha = 1 speed and direction never change: every update keeps the velocity."""
    p = GaussMarkovParams(alpha=1.0, mean_speed_mps=2.0, speed_sigma_mps=1.0, direction_sigma_rad=1.0)
    legs = _one_robot((10.0, 50.0), 0.0, p, 20.0)
    moving = legs[legs["cause"] != "start"].iloc[1:] if (legs["cause"] == "start").sum() > 1 else legs.iloc[1:]
    assert np.allclose(moving[["vx_mps", "vy_mps"]].to_numpy(), [2.0, 0.0])


def test_gauss_markov_border_reverses_the_velocity_and_mirrors_the_mean_direction():
    """Heading east: the first update that would end beyond the right border turns the
    robot west, and so do the following ones (the mean direction was mirrored to pi)."""
    p = GaussMarkovParams(alpha=0.5, mean_speed_mps=2.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0)
    legs = _one_robot((97.0, 50.0), 0.0, p, 10.5)
    v = legs[["vx_mps", "vy_mps"]].to_numpy()[1:]
    assert v[0, 0] > 0 and np.all(v[1:, 0] < 0), v
    assert np.allclose(v[:, 1], 0.0)


def test_gauss_markov_robot_that_would_still_leave_slides_along_the_border():
    """An interval's travel longer than the room left: the position is clamped as ns-3 clamps it."""
    legs = _clamped_legs(np.array([99.0, 50.0]), np.array([3.0, 4.0]), 1.0, 100.0)
    assert legs[0][0] == 0.0 and np.allclose(legs[0][1], [3.0, 4.0])
    assert legs[1][0] == pytest.approx(1.0 / 3.0) and np.allclose(legs[1][1], [0.0, 4.0])


@pytest.mark.slow
def test_gauss_markov_robots_stay_in_the_area():
    """Every leg starts and ends in the square (a straight leg between them stays in it)."""
    frames = _run(["mobility.model=gauss_markov", "world.n_robots=20", "duration_s=200", "mobility.mean_speed_mps=5"])
    xy = _positions_at_leg_ends(frames["legs"], 200.0)
    assert xy.min() >= -1e-9 and xy.max() <= 1000.0 + 1e-9


@pytest.mark.slow
def test_gauss_markov_speeds_have_the_stated_mean_and_lag_one_autocorrelation():
    """Successive updates' speeds: mean ``mean_speed_mps`` and lag-one autocorrelation
    ``alpha``, each within 4 standard errors estimated across the (independent) robots."""
    alpha, mean, sigma = 0.7, 3.0, 0.5
    frames = _run(
        [
            "mobility.model=gauss_markov",
            "world.n_robots=60",
            "duration_s=400",
            f"mobility.alpha={alpha}",
            f"mobility.mean_speed_mps={mean}",
            f"mobility.speed_sigma_mps={sigma}",
            "world.side_m=5000",
        ]
    )
    legs = frames["legs"]
    updates = legs[legs["cause"].isin(["start", "turn"]) & (legs["t_s"] > 0) | (legs["cause"] == "start")]
    means, corrs = [], []
    for _, g in updates.groupby("robot"):
        s = np.hypot(g["vx_mps"], g["vy_mps"]).to_numpy()
        s = s[s > 0]
        means.append(s.mean())
        a, b = s[:-1] - s.mean(), s[1:] - s.mean()
        corrs.append((a * b).sum() / (a * a).sum())
    means, corrs = np.array(means), np.array(corrs)
    assert abs(means.mean() - mean) < 4 * means.std(ddof=1) / math.sqrt(len(means))
    assert abs(corrs.mean() - alpha) < 4 * corrs.std(ddof=1) / math.sqrt(len(corrs)) + 1.0 / 400


def test_rpgm_groups_are_consecutive_robots():
    """Robots g*size .. (g+1)*size - 1 form group g; the last group may be smaller."""
    assert [g.tolist() for g in groups(7, 3)] == [[0, 1, 2], [3, 4, 5], [6]]


def test_rpgm_every_member_stays_within_group_radius_of_its_reference_point():
    """At every instant (checked on a fine grid of times against the reference point's
    track, linear between its rows) each member is within ``group_radius_m`` of it."""
    r, size, t_end = 40.0, 4, 300.0
    frames = _run(
        [
            "mobility.model=rpgm",
            "world.n_robots=12",
            f"duration_s={t_end}",
            f"mobility.group_size={size}",
            f"mobility.group_radius_m={r}",
            "mobility.pause_s=3",
            "mobility.speed_min_mps=5",
            "mobility.speed_max_mps=10",
        ]
    )
    legs, ref = frames["legs"], frames["reference_points"]
    assert len(ref) > 10
    times = np.linspace(0.0, t_end, 3001)
    worst = 0.0
    for robot, g in legs.groupby("robot"):
        track = ref[ref["group"] == robot // size].sort_values("t_s", kind="stable")
        rx = np.interp(times, track["t_s"], track["x_m"])
        ry = np.interp(times, track["t_s"], track["y_m"])
        k = np.searchsorted(g["t_s"].to_numpy(), times, side="right") - 1
        leg = g.iloc[k]
        dt = times - leg["t_s"].to_numpy()
        x = leg["x_m"].to_numpy() + leg["vx_mps"].to_numpy() * dt
        y = leg["y_m"].to_numpy() + leg["vy_mps"].to_numpy() * dt
        worst = max(worst, float(np.hypot(x - rx, y - ry).max()))
    assert 0.5 * r < worst <= r + 1e-6


def test_rpgm_members_stay_in_the_area():
    """The reference points keep ``group_radius_m`` from every border, so members stay inside."""
    frames = _run(["mobility.model=rpgm", "world.n_robots=15", "duration_s=300", "mobility.group_radius_m=80"])
    xy = _positions_at_leg_ends(frames["legs"], 300.0)
    assert xy.min() >= 0.0 and xy.max() <= 1000.0


@pytest.mark.parametrize(
    "settings, key",
    [
        (["mobility.model=rpgm", "mobility.group_radius_m=600"], "mobility.group_radius_m"),
        # Half the side leaves the reference points no room at all.
        (["mobility.model=rpgm", "world.side_m=1000", "mobility.group_radius_m=500"], "mobility.group_radius_m"),
        (["mobility.model=rpgm", "world.torus=true"], "mobility.model"),
        (["mobility.model=rpgm", "mobility.group_size=0"], "mobility.group_size"),
        (["mobility.model=rpgm", "mobility.offset_law=uniform"], "mobility.offset_law"),
        (["mobility.model=gauss_markov", "mobility.alpha=1.5"], "mobility.alpha"),
        (["mobility.model=gauss_markov", "mobility.update_interval_s=0"], "mobility.update_interval_s"),
        (["mobility.model=gauss_markov", "world.torus=true"], "mobility.model"),
    ],
)
def test_bad_group_and_smooth_mobility_keys_name_the_key(settings, key):
    with pytest.raises(ConfigError) as err:
        load(None, settings)
    assert str(err.value).startswith(key)


class _Draws:
    """A stand-in generator: ``random()`` and ``uniform()`` give the listed values in turn."""

    def __init__(self, randoms, angles):
        self.randoms, self.angles = list(randoms), list(angles)

    def random(self):
        return self.randoms.pop(0)

    def uniform(self, lo, hi):
        return self.angles.pop(0)


def test_rpgm_offset_distance_is_uniform_on_the_radius_by_default():
    """By default (Hong et al. 1999, BonnMotion) an offset's distance is uniform on [0, R]:
    mean R / 2, a quarter of them within R / 4 (uniform over the disk would give 2R/3, 1/16)."""
    rng = np.random.default_rng(5)
    law = RpgmParams().offset_law
    assert law == OffsetLaw.UNIFORM_RADIUS
    r = np.array([np.hypot(*draw_offset(rng, 10.0, law)) for _ in range(20000)])
    assert r.max() <= 10.0
    assert abs(r.mean() - 5.0) < 4 * 10.0 / math.sqrt(12 * 20000)
    assert abs((r < 2.5).mean() - 0.25) < 4 * math.sqrt(0.25 * 0.75 / 20000)


def test_rpgm_offset_law_uniform_area_draws_uniformly_over_the_disk():
    """``mobility.offset_law = "uniform_area"``: offsets uniform over the disk, distance mean 2R/3."""
    rng = np.random.default_rng(6)
    law = load(None, ["mobility.model=rpgm", "mobility.offset_law=uniform_area"]).mobility.params.offset_law
    r = np.array([np.hypot(*draw_offset(rng, 10.0, law)) for _ in range(20000)])
    assert abs(r.mean() - 20.0 / 3) < 4 * math.sqrt(50.0 - (20.0 / 3) ** 2) / math.sqrt(20000)


def test_rpgm_member_offset_too_fast_is_drawn_again():
    """A new offset that would make the member faster than ``speed_max_mps`` is drawn again
    (BonnMotion's rule): here the first draw, 10 m ahead of a reference point that moves
    5 m, would take the member 15 m in a leg that allows 10, and is refused."""
    m = RpgmParams(speed_max_mps=1.0, group_radius_m=10.0)
    # The reference point moves 5 m east in 10 s; the member may move at most 10 m.
    rng = _Draws(randoms=[1.0, 0.0], angles=[0.0, 0.0])
    new = member_offset(rng, m, np.zeros(2), np.array([5.0, 0.0]), 10.0)
    assert np.allclose(new, [0.0, 0.0]) and not rng.randoms


def test_rpgm_member_keeps_its_offset_when_no_draw_is_slow_enough():
    """After MAX_DRAWS refused draws (or on a leg of no time) the member keeps its offset and
    so moves with its reference point, never faster than it."""
    m = RpgmParams(speed_max_mps=1.0, group_radius_m=10.0)
    old = np.array([3.0, 4.0])
    far = _Draws(randoms=[1.0] * MAX_DRAWS, angles=[0.0] * MAX_DRAWS)
    assert np.array_equal(member_offset(far, m, old, np.array([10.0, 0.0]), 10.0), old)
    assert np.array_equal(member_offset(np.random.default_rng(1), m, old, np.zeros(2), 0.0), old)


def test_rpgm_members_are_never_faster_than_speed_max():
    """No member leg is faster than ``speed_max_mps`` (offsets redrawn rather than rushed),
    with reference points at up to that speed and a radius large against short legs."""
    frames = _run(
        [
            "mobility.model=rpgm",
            "world.n_robots=40",
            "duration_s=1500",
            "world.side_m=400",
            "mobility.group_radius_m=60",
            "mobility.speed_min_mps=1",
            "mobility.speed_max_mps=2",
        ]
    )
    legs = frames["legs"]
    speed = np.hypot(legs["vx_mps"], legs["vy_mps"])
    assert speed.max() <= 2.0 * (1 + 1e-9)
    assert (speed > 1.9).sum() > 0


class _Scripted:
    """A stand-in random generator: uniform draws give ``u``, normal draws the pairs given,
    then zeros."""

    def __init__(self, u: float, normals):
        self.u, self.normals = u, list(normals)

    def uniform(self, lo, hi, size=None):
        return self.u

    def standard_normal(self, size):
        return np.asarray(self.normals.pop(0), float) if self.normals else np.zeros(size)


def _updates(params: GaussMarkovParams, rng, until_s: float) -> pd.DataFrame:
    """One robot in the middle of a wide square: its legs, one per update."""
    env = simpy.Environment()
    st = RobotState(1, 10_000.0, 10.0)
    st.place(np.array([[5000.0, 5000.0]]))
    env.process(gauss_markov_robot(env, st, params, 10_000.0, 0, rng))
    env.run(until=until_s)
    legs = st.legs()
    # The leg an update sets replaces the placement's at t = 0.
    return legs.groupby("t_s").last()


def test_gauss_markov_mean_speed_is_reverted_to_at_rate_alpha():
    """A kick of one standard normal at the first update, none after: the speed starts at
    the mean, is lifted by sqrt(1 - alpha^2) sigma, and the lift decays by alpha an update."""
    alpha, mean, sigma = 0.75, 2.0, 0.4
    p = GaussMarkovParams(alpha=alpha, mean_speed_mps=mean, speed_sigma_mps=sigma, direction_sigma_rad=0.3)
    legs = _updates(p, _Scripted(0.0, [(1.0, 0.0)]), 4.5)
    speeds = np.hypot(legs["vx_mps"], legs["vy_mps"]).to_numpy()
    lift = math.sqrt(1 - alpha**2) * sigma
    assert speeds == pytest.approx([mean + lift * alpha**k for k in range(5)], rel=1e-12)
    assert np.allclose(legs["vy_mps"], 0.0)  # no kick to the direction: still east


def test_gauss_markov_direction_is_reverted_to_its_mean_at_rate_alpha_by_its_own_draw():
    """The direction's kick is the second normal, scaled by sqrt(1 - alpha^2) times the
    direction's sigma (not the speed's), and decays by alpha an update; the speed stays."""
    alpha, sigma_rad = 0.75, 0.3
    p = GaussMarkovParams(alpha=alpha, mean_speed_mps=2.0, speed_sigma_mps=0.4, direction_sigma_rad=sigma_rad)
    legs = _updates(p, _Scripted(0.0, [(0.0, 1.0)]), 4.5)
    headings = np.arctan2(legs["vy_mps"], legs["vx_mps"]).to_numpy()
    kick = math.sqrt(1 - alpha**2) * sigma_rad
    assert headings == pytest.approx([kick * alpha**k for k in range(5)], rel=1e-12)
    assert np.hypot(legs["vx_mps"], legs["vy_mps"]).to_numpy() == pytest.approx(2.0, rel=1e-12)


def test_gauss_markov_updates_after_the_first_are_turns():
    p = GaussMarkovParams(alpha=0.5, mean_speed_mps=1.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0)
    legs = _one_robot((50.0, 50.0), 0.0, p, 3.5)
    moving = legs[legs["t_s"] > 0]
    assert legs["cause"].iloc[0] == "start" and moving["cause"].tolist() == ["turn"] * 3


def test_gauss_markov_mean_directions_cover_the_whole_circle():
    """Each robot's mean direction is uniform on [0, 2 pi): a team heads every way, south too."""
    p = GaussMarkovParams(alpha=1.0, mean_speed_mps=1.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0)
    rng = np.random.default_rng(4)
    headings = []
    for _ in range(40):
        legs = _updates(p, rng, 0.5)
        headings.append(math.atan2(legs["vy_mps"].iloc[0], legs["vx_mps"].iloc[0]))
    quadrants = np.floor(np.mod(headings, 2 * math.pi) / (math.pi / 2))
    assert set(quadrants.tolist()) == {0.0, 1.0, 2.0, 3.0}


def test_gauss_markov_speed_sigmas_below_light_are_twelve():
    """The keys are refused only when the mean plus twelve standard deviations passes light."""
    from types import SimpleNamespace

    from netsim.mobility.gauss_markov import check

    from netsim.geometry import SPEED_OF_LIGHT_MPS

    config = SimpleNamespace(world=SimpleNamespace(torus=False))
    sigma = SPEED_OF_LIGHT_MPS / 13
    check(GaussMarkovParams(mean_speed_mps=0.5 * sigma, speed_sigma_mps=sigma), config)
    with pytest.raises(ConfigError, match="12 x it"):
        check(GaussMarkovParams(mean_speed_mps=1.5 * sigma, speed_sigma_mps=sigma), config)


def test_gauss_markov_border_at_the_top_mirrors_the_mean_direction_downward():
    """Heading north into the top border of a wide rectangle: the velocity's y is reversed
    and the mean direction mirrored to -pi/2, so the following updates head south too."""
    from netsim.area import Bounds

    p = GaussMarkovParams(alpha=0.5, mean_speed_mps=2.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0)
    env = simpy.Environment()
    st = RobotState(1, 300.0, 10.0)
    st.place(np.array([[50.0, 97.0]]))
    env.process(gauss_markov_robot(env, st, p, Bounds(0.0, 0.0, 300.0, 100.0), 0, _Fixed(math.pi / 2)))
    env.run(until=10.5)
    legs = st.legs()
    v = legs[["vx_mps", "vy_mps"]].to_numpy()[1:]
    assert v[0, 1] > 0 and np.all(v[1:, 1] < 0), v
    assert np.allclose(v[:, 0], 0.0)


def test_gauss_markov_interval_ending_exactly_on_the_border_is_not_turned():
    """The area is closed: an update whose interval ends on the border itself goes there,
    and only the next, which would leave, turns back."""
    p = GaussMarkovParams(alpha=1.0, mean_speed_mps=2.0, speed_sigma_mps=0.0, direction_sigma_rad=0.0)
    legs = _one_robot((4.0, 50.0), math.pi, p, 2.5).groupby("t_s").last()
    assert legs.loc[[0.0, 1.0], "vx_mps"].tolist() == [-2.0, -2.0]
    assert legs.loc[2.0, "x_m"] == 0.0 and legs.loc[2.0, "vx_mps"] == 2.0


def test_gauss_markov_keys_refuse_a_torus_and_allow_a_hundred_radians():
    from types import SimpleNamespace

    from netsim.mobility.gauss_markov import _at_most_a_hundred_radians, check

    with pytest.raises(ConfigError, match="world.torus = false"):
        check(GaussMarkovParams(), SimpleNamespace(world=SimpleNamespace(torus=True)))
    assert _at_most_a_hundred_radians(100.0) is None and _at_most_a_hundred_radians(0.0) is None
    assert _at_most_a_hundred_radians(100.5) is not None


def test_rpgm_group_radius_just_under_half_the_side_is_allowed():
    assert load(None, ["mobility.model=rpgm", "world.side_m=1000", "mobility.group_radius_m=499.9"])


def test_rpgm_member_offset_at_exactly_the_top_speed_is_kept():
    """BonnMotion's bound is inclusive: a member moving exactly ``speed_max_mps`` is not
    redrawn. The reference point moves 5 m east in 10 s and the offset 5 m east: 10 m in 10 s."""
    m = RpgmParams(speed_max_mps=1.0, group_radius_m=10.0)
    rng = _Draws(randoms=[0.5, 0.0], angles=[0.0, 0.0])
    new = member_offset(rng, m, np.zeros(2), np.array([5.0, 0.0]), 10.0)
    assert new.tolist() == [5.0, 0.0] and rng.randoms == [0.0]


def test_rpgm_reference_points_move_at_speeds_drawn_between_the_bounds_and_resume_after_a_pause():
    """Each leg of a reference point takes its distance over a speed drawn in [speed_min,
    speed_max] (not always the top one), and the members' legs after a pause are pause ends."""
    frames = _run(
        [
            "mobility.model=rpgm",
            "world.n_robots=6",
            "mobility.group_size=3",
            "duration_s=400",
            "mobility.speed_min_mps=1",
            "mobility.speed_max_mps=5",
            "mobility.pause_s=2",
            "mobility.group_radius_m=20",
        ]
    )
    ref = frames["reference_points"]
    speeds = []
    for _, g in ref.groupby("group"):
        xy, t = g[["x_m", "y_m"]].to_numpy(), g["t_s"].to_numpy()
        # Rows come in pairs: a leg's start and its end.
        speeds += (np.hypot(*(xy[1::2] - xy[0::2]).T) / (t[1::2] - t[0::2])).tolist()
    assert 1.0 - 1e-9 <= min(speeds) and max(speeds) <= 5.0 + 1e-9 and min(speeds) < 4.0
    assert "pause_end" in set(frames["legs"]["cause"])
