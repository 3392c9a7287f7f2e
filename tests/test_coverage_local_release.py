"""The local plan's release of a silent robot (docs/model.md 5.1, "Release"; mobility/local.py,
:class:`Silence`): on a channel that loses no frame a robot lets go of a robot it has heard no
Ack of for longer than the largest gap between two Acks, and rule 1 then certifies a detour's
links up over the window before the step; under loss it keeps the robot for release_s."""

from __future__ import annotations

import numpy as np
import pytest
from netsim.mobility.local import NO_WALLS, Lists, Memory, let_go, silence_of, silent

from netsim import config
from netsim.run import ack_timing, build, execute
from netsim.tools.validate import coverage_settings
from tests.oracles import local as oracle

RC = 100.0
V = 2.0
T0 = 10.0
PERIOD_S, JITTER_S, LATENCY_S = 1.0, 0.05, 0.001
SILENCE = silence_of(PERIOD_S, JITTER_S, LATENCY_S, 0.0)


def memory_of(xy_heard, sent_s):
    n = len(sent_s)
    m = Memory(n)
    m.xy[:] = np.asarray(xy_heard, dtype=float)
    m.sent_s[:] = np.asarray(sent_s, dtype=float)
    return m


def told(m, release_s=20.0):
    """Every robot holds, from every robot it remembers, that robot's memory as its list."""
    lists = Lists(len(m.sent_s), 1)
    lists.take(m, m.sent_s[np.isfinite(m.sent_s)].min(initial=T0) - 1.0, release_s)
    return lists.heard(m.known(T0, release_s), m.sent_s, release_s)


def test_release_a_robot_is_silent_once_it_heard_no_ack_for_longer_than_the_largest_gap():
    """The largest gap between two Acks of a robot as heard is ack period + ack jitter + the
    channel's delay jitter: a robot whose latest Ack arrived a little less than that ago is
    not silent, one a little more is; a robot never heard is not silent (not remembered)."""
    assert SILENCE.gap_s == pytest.approx(PERIOD_S + JITTER_S, abs=1e-5)
    assert silence_of(1.0, 0.05, 0.001, 0.02).gap_s == pytest.approx(1.07, abs=1e-5)
    now, lead = 20.0, LATENCY_S
    m = Memory(3)
    heard_s = np.array([now - (PERIOD_S + JITTER_S) + 1e-4, now - (PERIOD_S + JITTER_S) - 1e-4])
    m.hear(np.array([0, 0]), np.array([1, 2]), np.zeros((2, 2)), heard_s, lead)
    quiet = silent(m, now, lead, SILENCE)
    assert not quiet[0, 1] and quiet[0, 2]
    assert not quiet[1].any() and not quiet[2].any()
    assert not silent(m, now, lead, None).any()


@pytest.mark.filterwarnings("ignore::netsim.config.ConfigWarning")
def test_release_is_on_only_where_the_channel_loses_no_frame():
    """The plan is given the Acks' timing when built (netsim.run.ack_timing), as the run's
    protocol declares it: lossless only with the Bernoulli loss model at loss_probability =
    0 and no shared medium; the distance loss model (which drops near the range's edge
    whatever its floor) and Gilbert-Elliott count as lossy, and a protocol without Acks
    gives nothing."""
    base = coverage_settings("shadowing 4 dB", "local", 6, 0.0, 1, 30.0)

    def timing(*extra):
        cfg = config.load(None, base + list(extra))
        return ack_timing(build(cfg).models["protocol"], cfg.channel)

    assert timing() == (PERIOD_S, JITTER_S, True)
    assert timing("protocol.ack_period_s=2.0") == (2.0, JITTER_S, True)
    assert not timing("channel.loss_probability=0.01").lossless
    # (the distance law is refused under shadowing: it would lose every frame past the range)
    unshadowed = "channel.shadowing_sigma_db=0"
    assert not timing('channel.loss_model="distance"', "channel.loss_probability=0", unshadowed).lossless
    assert not timing('channel.loss_model="gilbert_elliott"').lossless
    assert not timing('channel.mac="aloha"', "coverage.enabled=false").lossless
    assert timing('protocol.model="none"', "coverage.enabled=false") is None


def two_robots(loss):
    """Two robots of the local plan 30 m apart (unit disk, range 100 m), robot 1 switched off
    at 15 s: from then on robot 0 hears no Ack of it."""
    overrides = coverage_settings("unit disk", "local", 2, loss, 1, 30.0) + ["world.centre_side_m=30"]
    sim = build(config.load(None, overrides))
    sim.run(15.0)
    ctl = sim.models["coverage"]
    assert ctl.kept[0, 1] and not ctl.silent.any()
    sim.state.alive[1] = False
    return sim, ctl


def test_release_a_robot_lets_go_of_a_silent_robot_on_a_lossless_channel():
    """On a lossless channel robot 0 lets go of robot 1 at the first step after more than
    the largest gap between two Acks without one (though it still remembers it)."""
    sim, ctl = two_robots(0.0)
    assert ctl.silence is not None
    sim.run(16.0)  # the step at 16 s: the latest Ack is less than the gap old
    assert ctl.kept[0, 1]
    sim.run(18.0)
    assert ctl.silent[0, 1] and not ctl.kept[0, 1]
    assert ctl.heard.known[0, 1]


def test_release_under_loss_a_robot_keeps_a_silent_robot_for_release_s():
    """Under loss a missed Ack says nothing of the link: robot 0 keeps robot 1 while it
    remembers it (release_s after its latest Ack)."""
    sim, ctl = two_robots(0.01)
    assert ctl.silence is None
    sim.run(25.0)
    assert ctl.kept[0, 1] and not ctl.silent.any()


def triangle(sent_s):
    """Robots 0 and 1 120 m apart, robot 2 97.5 m from each; all heard at ``sent_s``."""
    pos = np.array([[0.0, 0.0], [120.0, 0.0], [60.0, np.sqrt(97.5**2 - 60.0**2)]])
    n = len(pos)
    s = np.full((n, n), float(sent_s))
    np.fill_diagonal(s, -np.inf)
    return pos, memory_of(np.broadcast_to(pos[None], (n, n, 2)).copy(), s)


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_links_are_certified_up_over_the_window_before_the_step(monkeypatch, compiled):
    """Rule 1 with the release: a detour's link counts only if it is surely up over the whole
    window before t0, each end anywhere it may have been over the window as the robot knows
    it (the speed cap, or the leg its Acks carried). Links of 98.5 m at
    most at t0 are surely up then, not over a window of about a second at 2 m/s, unless
    the robots held."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    pos, m = triangle(T0 - 0.5)
    assert let_go(pos, m, told(m), T0, V, 10.0, RC)[0, 1]
    assert not let_go(pos, m, told(m), T0, V, 10.0, RC, window_s=SILENCE.window_s)[0, 1]
    near = pos.copy()
    near[2, 1] -= 5.0  # 4 m shorter links: certified over the window too
    m2 = memory_of(np.broadcast_to(near[None], (3, 3, 2)).copy(), m.sent_s)
    assert let_go(near, m2, told(m2), T0, V, 10.0, RC, window_s=SILENCE.window_s)[0, 1]
    # Robots whose Acks (and robot 0's own leg) say they have held since before the window
    # travelled nothing over it: certified as at t0.
    m.leg_velocity_mps[:] = 0.0
    m.leg_from_s[:] = T0 - 5.0
    assert let_go(pos, m, told(m), T0, V, 10.0, RC, window_s=SILENCE.window_s)[0, 1]


@pytest.mark.slow
def test_detour_kernel_over_a_window_agrees_with_its_oracle(monkeypatch):
    """Rule 1's kernel with a window, plain and compiled, lets go of exactly the links its
    numpy oracle does, in open space and on a map (a detour's link surely clear of walls
    over the window), with no leg known (the cap all along) and with legs known that
    started before and within the window, in every direction, some robots holding."""
    from netsim.mobility.local import walls_of

    from tests.test_coverage_local import ORIGIN, RES, blocks_map, random_scene

    map_walls = walls_of(blocks_map([(100, 50, 102, 250), (150, 100, 300, 101)]), ORIGIN, RES)
    rng = np.random.default_rng(5)
    differs = legs_matter = False
    for seed in range(6):
        pos, m = random_scene(seed, n=30)
        heard = told(m)
        blind = let_go(pos, m, heard, T0, V, 10.0, RC, map_walls, window_s=3.0)
        if seed >= 2:
            heading = rng.uniform(0.0, 2 * np.pi, m.sent_s.shape)
            speed = V * np.where(rng.random(m.sent_s.shape) < 0.3, 0.0, rng.random(m.sent_s.shape))
            m.leg_velocity_mps[:] = (speed * np.stack([np.cos(heading), np.sin(heading)])).transpose(1, 2, 0)
            m.leg_from_s[:] = T0 - rng.uniform(0.0, 4.0, m.sent_s.shape)
            # Some legs ended before t0 (no later Ack told of the next): the cap after them.
            ended = rng.random(m.sent_s.shape) < 0.3
            m.leg_until_s[:] = np.where(ended, np.minimum(T0 - rng.uniform(0.0, 2.0, ended.shape), T0), np.inf)
            legs_matter |= bool((let_go(pos, m, heard, T0, V, 10.0, RC, map_walls, window_s=3.0) != blind).any())
        for walls in (NO_WALLS, map_walls):
            want = oracle.let_go(pos, m, heard, T0, V, 10.0, RC, walls, 3.0)
            for compiled in ("0", "1"):
                monkeypatch.setenv("NETSIM_COMPILED", compiled)
                got = let_go(pos, m, heard, T0, V, 10.0, RC, walls, window_s=3.0)
                assert (got == want).all(), (seed, compiled)
            differs |= bool((got != let_go(pos, m, heard, T0, V, 10.0, RC, walls)).any())
    assert differs and legs_matter


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_a_robot_that_moved_along_a_corridor_is_followed_along_its_leg_over_the_window(monkeypatch, compiled):
    """Rule 1 with the release on a map: robots 0, 2 and 1 stand 15 m apart along a 2 m
    corridor, 2 at 0.3 m from its south wall, and 2 has moved along it at the cap (2 m/s)
    since the step before. Over the window (1.05 s, in 8 pieces of 0.13 s) each end of a
    detour's link is where its known leg puts it, give or take its travel over a piece
    (0.16 m at most, on the piece where the leg starts), so 0 lets go of 1 through 2. In 4
    pieces that piece would leave 0.42 m, and 0 would keep 1; had 2's leg been unknown, it
    might have swept 2.1 m across the corridor and 0 keeps 1."""
    from netsim.mobility.local import walls_of

    from tests.test_coverage_local import ORIGIN, RES, blocks_map

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    walls = walls_of(blocks_map([(0, -2, 100, 0), (0, 2, 100, 4)]), ORIGIN, RES)
    pos = np.array([[10.0, 1.0], [40.0, 1.0], [25.0, 0.3]])
    sent = np.full((3, 3), T0)
    np.fill_diagonal(sent, -np.inf)
    m = memory_of(np.broadcast_to(pos[None], (3, 3, 2)).copy(), sent)
    m.leg_velocity_mps[:] = 0.0
    m.leg_velocity_mps[:, 2] = (V, 0.0)
    m.leg_from_s[:] = T0 - PERIOD_S
    window = SILENCE.window_s
    assert let_go(pos, m, told(m), T0, V, 10.0, 30.0, walls)[0, 1]
    assert let_go(pos, m, told(m), T0, V, 10.0, 30.0, walls, window_s=window)[0, 1]
    assert (
        let_go(pos, m, told(m), T0, V, 10.0, 30.0, walls, window_s=window)
        == oracle.let_go(pos, m, told(m), T0, V, 10.0, 30.0, walls, window)
    ).all()
    m.leg_velocity_mps[:, 2] = np.nan
    assert not let_go(pos, m, told(m), T0, V, 10.0, 30.0, walls, window_s=window)[0, 1]


@pytest.mark.slow
def test_release_a_robot_lets_go_only_of_links_down_within_the_window():
    """The release's premise, on a lossless run under 4 dB shadowing: whenever a robot lets
    go of a robot as silent, the link (links.parquet) was down at some instant of the window
    before the step; so no link up over the window is ever let go of for silence."""
    from netsim.mobility import coverage

    seen = []
    plan_local = coverage.CoverageController._plan_local

    def watched(self, step):
        plan = plan_local(self, step)
        i, j = np.nonzero(self.silent & self.heard.known)
        seen.append((step.t_s, i, j))
        return plan

    coverage.CoverageController._plan_local = watched
    try:
        r = execute(config.load(None, coverage_settings("shadowing 4 dB", "local", 20, 0.0, 1, 150.0)))
    finally:
        coverage.CoverageController._plan_local = plan_local
    window = r.sim.models["coverage"].silence.window_s
    links = r.frames["links"]
    up = {}
    for a, b, t_up, t_down in links[["a", "b", "t_up_s", "t_down_s"]].itertuples(index=False):
        up.setdefault((min(a, b), max(a, b)), []).append((t_up, t_down))
    count = 0
    for t0, robots, others in seen:
        for i, j in zip(robots.tolist(), others.tolist()):
            count += 1
            spans = up.get((min(i, j), max(i, j)), [])
            # Up over the whole window: one up interval covers [t0 - window, t0].
            assert not any(lo <= t0 - window and (np.isnan(hi) or hi > t0) for lo, hi in spans), (t0, i, j)
    assert count > 100


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_a_measured_link_is_certified_over_the_pair_travel_from_the_windows_start(monkeypatch, compiled):
    """Rule 1 under shadowing with the release: a detour's link measured beyond the sure
    distance counts as up over the window when its shadowing stays within range over the
    pair's travel from the window's start (earlier than the measurement), not only from the
    measurement: two robots at the speed cap travel 0.14 m in the 0.2 s since their Acks,
    0.76 m over the window, enough for the shadowing's plausible change to shorten links
    of about 43 m measured at 6 dB below their length."""
    from tests.test_coverage_local_fade import SURE, fade, heard_over_steps, measured_memory

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    f = fade()
    v = f.speed_mps
    pos = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 15.0]])
    m = measured_memory(pos, 6.0, T0 - 0.2)
    m.leg_velocity_mps[:] = (v, 0.0)  # every robot at the cap since before the window
    m.leg_from_s[:] = T0 - 5.0
    held = heard_over_steps(m)
    assert let_go(pos, m, held, T0, v, 7.5, SURE, fade=f)[0, 1]
    assert not let_go(pos, m, held, T0, v, 7.5, SURE, fade=f, window_s=SILENCE.window_s)[0, 1]


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_a_measured_links_travel_counts_the_cap_after_the_known_leg_ended(monkeypatch, compiled):
    """Rule 1 under shadowing with the release: robots whose Acks told of a leg on which they
    held may have moved at the cap since that leg ended (their next step, of which no Ack
    told), so a detour's measured links are certified over that travel: with the legs
    holding through t0 robot 0 lets go of robot 1 through 2, with the legs ended a second
    before the window it cannot."""
    from tests.test_coverage_local_fade import SURE, fade, heard_over_steps, measured_memory

    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    f = fade()
    pos = np.array([[0.0, 0.0], [80.0, 0.0], [40.0, 15.0]])
    m = measured_memory(pos, 6.0, T0 - 0.2)
    m.leg_velocity_mps[:] = 0.0
    m.leg_from_s[:] = T0 - 5.0
    held = heard_over_steps(m)
    window = SILENCE.window_s
    assert let_go(pos, m, held, T0, f.speed_mps, 7.5, SURE, fade=f, window_s=window)[0, 1]
    m.leg_until_s[:] = T0 - 4.0
    np.fill_diagonal(m.leg_until_s, np.inf)
    assert not let_go(pos, m, held, T0, f.speed_mps, 7.5, SURE, fade=f, window_s=window)[0, 1]


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_a_silent_robots_link_is_no_detours_link_though_the_robot_is_still_a_node(monkeypatch, compiled):
    """Rule 1 with the release: a robot's link to a robot it counts silent was down in the
    window, so it never enters a detour; the silent robot is still a node, reached through
    others (robot 0 lets go of robot 1 through 3 and the silent 2; when it does not remember
    3, the only detour starts with its link to 2, and it keeps 1)."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    pos = np.array([[0.0, 0.0], [90.0, 0.0], [60.0, 20.0], [30.0, 20.0]])
    n = len(pos)
    s = np.full((n, n), T0 - 0.5)
    np.fill_diagonal(s, -np.inf)
    m = memory_of(np.broadcast_to(pos[None], (n, n, 2)).copy(), s)
    quiet = np.zeros((n, n), dtype=bool)
    quiet[0, 2] = True
    assert let_go(pos, m, told(m), T0, V, 10.0, RC, silent_of=quiet)[0, 1]
    m.sent_s[0, 3] = -np.inf
    assert let_go(pos, m, told(m), T0, V, 10.0, RC)[0, 1]
    assert not let_go(pos, m, told(m), T0, V, 10.0, RC, silent_of=quiet)[0, 1]
    assert (
        oracle.let_go(pos, m, told(m), T0, V, 10.0, RC, NO_WALLS, 0.0, quiet)
        == let_go(pos, m, told(m), T0, V, 10.0, RC, silent_of=quiet)
    ).all()


def test_detour_a_window_piece_holds_every_position_its_end_can_have_had():
    """Rule 1's pieces of the window: wherever an end truly was at an instant of a piece
    (the cap before its leg, the leg's velocity from the leg's start until its next step,
    which may come before t0, the cap after), it lies in the disk the piece gives it from
    what the robot knows (the position carried along the leg to t0 and its uncertainty
    there, :meth:`Memory.at`), on sampled trajectories of every kind: leg started before,
    within and at the end of the window, and no leg known."""
    from netsim.mobility import _local_kernels as kernels

    rng = np.random.default_rng(3)
    pieces = kernels.WINDOW_PIECES
    t0 = T0
    for _ in range(400):
        cap = rng.uniform(0.5, 3.0)
        window = rng.choice([rng.uniform(0.01, 3.0), SILENCE.window_s])
        opens = t0 - window
        kind = rng.integers(4)
        leg_from = [opens - rng.uniform(0.0, 3.0), rng.uniform(opens, t0), t0, np.inf][kind]
        known = kind != 3
        v = rng.normal(size=2)
        v *= rng.uniform(0.0, cap) / np.hypot(*v) if known else 0.0
        # The leg ends at the robot's next step: at t0, or earlier for a stale Ack.
        until = t0 if rng.random() < 0.5 or not known else rng.uniform(min(leg_from, t0), t0)
        start = min(leg_from, t0)
        at_until = rng.normal(size=2) * 10.0
        after, before = (u / np.hypot(*u) for u in rng.normal(size=(2, 2)))

        def truly(t, at_until=at_until, v=v, until=until, start=start, cap=cap, after=after, before=before):
            if t >= until:
                return at_until + cap * rng.uniform(0.0, 1.0) * after * (t - until)
            if t >= start:
                return at_until - v * (until - t)
            return at_until - v * (until - start) - cap * rng.uniform(0.0, 1.0) * before * (start - t)

        if known:
            # What Memory.at gives: the Ack's position carried along the leg to its end (off
            # by the send time's jitter along it), and the uncertainty that covers the rest.
            jitter = rng.uniform(0.0, 0.05)
            q = at_until + v * jitter * rng.uniform(-1.0, 1.0)
            e = np.hypot(*v) * jitter + cap * (t0 - until)
            leg_s, speed = min(max(leg_from, opens), t0), np.hypot(*v)
        else:
            e = cap * rng.uniform(0.0, 2.0)
            off = rng.normal(size=2)
            q = truly(t0) + e * rng.uniform(0.0, 1.0) * off / np.hypot(*off)
            leg_s, speed = t0, 0.0
        span = (t0 - opens) / pieces
        for p in range(pieces):
            s0 = opens + p * span
            s1 = t0 if p == pieces - 1 else opens + (p + 1) * span
            x, y, r = kernels.at_over(q[0], q[1], e, v[0], v[1], speed, leg_s, s0, s1, t0, cap)
            for t in np.linspace(s0, s1, 17):
                assert np.hypot(*(truly(t) - (x, y))) <= r + 1e-9, (kind, p, t)


@pytest.mark.parametrize("compiled", ["0", "1"])
def test_detour_the_legs_over_the_window_certify_every_link_the_whole_travel_does(monkeypatch, compiled):
    """Rule 1 over the window: following the ends along their legs only adds to what the
    disk of each end's whole travel certifies. Robot 2 moved at the cap toward 0 since the
    step before, 97.85 m from 0 at t0: within the whole travel's disk the link (0, 2) is
    surely within 100 m over the window, though on the piece where 2's leg started the
    leg's travel, counted both ways, would reach past it; 0 lets go of 1 through 2."""
    monkeypatch.setenv("NETSIM_COMPILED", compiled)
    pos = np.array([[0.0, 0.0], [137.85, 0.0], [97.85, 0.0]])
    sent = np.full((3, 3), T0)
    np.fill_diagonal(sent, -np.inf)
    m = memory_of(np.broadcast_to(pos[None], (3, 3, 2)).copy(), sent)
    m.leg_velocity_mps[:] = 0.0
    m.leg_from_s[:] = T0 - 5.0
    m.leg_velocity_mps[:, 2] = (-V, 0.0)
    m.leg_from_s[:, 2] = T0 - PERIOD_S
    window = SILENCE.window_s
    got = let_go(pos, m, told(m), T0, V, 10.0, 100.0, window_s=window)
    assert got[0, 1]
    assert (got == oracle.let_go(pos, m, told(m), T0, V, 10.0, 100.0, NO_WALLS, window)).all()


@pytest.mark.parametrize("release_s", ["inf", "1e12"])
def test_release_s_beyond_the_run_keeps_lists_back_to_its_start_and_no_more(release_s):
    """No Ack dates from before the run: a release_s longer than it (infinite: a robot
    never forgets) holds the lists of every control step of the run, not room for
    release_s / control_period_s of them, which overflowed or filled the memory."""
    extra = [f"coverage.release_s={release_s}", "coverage.start_s=0"]
    overrides = coverage_settings("unit disk", "local", 5, 0.1, 1, 6.0, extra=extra)
    sim = build(config.load(None, overrides))
    cov = sim.models["coverage"]
    assert cov.lists.depth == 6 + 2
    sim.run()
    assert sim.now == 6.0


@pytest.mark.slow
def test_a_local_plan_too_large_for_this_machine_is_refused_when_built_not_when_read():
    """The lists' memory is the running machine's concern: the configuration loads (a run's
    config.toml stays readable by view, figures and export on a smaller machine), and
    building the run refuses it naming coverage.release_s."""
    overrides = coverage_settings("unit disk", "local", 3000, 0.0, 1, 30000.0, extra=["coverage.release_s=inf"])
    cfg = config.load(None, overrides)
    with pytest.raises(config.ConfigError, match="coverage.release_s = inf: the local plan would hold"):
        build(cfg)
