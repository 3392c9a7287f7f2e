"""The colours and symbols the figures and the replay share."""

from netsim.tools import palette


def test_group_colours_are_matplotlibs_tab20():
    import matplotlib
    from matplotlib.colors import to_hex

    assert palette.GROUP_COLOURS == tuple(to_hex(c) for c in matplotlib.colormaps["tab20"].colors)


def test_groups_are_coloured_by_the_rank_of_their_leader():
    """Rank among every robot that was ever a leader, cycling through the palette."""
    ranks = palette.group_ranks(list(range(0, 100, 2)))
    assert ranks[0] == 0 and ranks[2] == 1 and ranks[40] == 0 and ranks[98] == 49 % 20


def test_every_role_has_a_marker_and_a_label():
    assert set(palette.MARKERS) == set(palette.LABELS) == {"alpha", "beta", "gamma", "gateway"}
