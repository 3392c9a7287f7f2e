"""The beacon workload's options that the reference programs share (simpy_reference_beacon.py,
ns3_beacon.py): values that would hang a program (a period of 0), divide by zero or run
something else than asked are refused in one line."""


def refuse_bad_workload(parser, args) -> None:
    """``parser.error`` (exit 2) on the first option of ``args`` out of its range."""
    for bad, why in (
        (args.n < 1, "--n must be at least 1"),
        (not args.rc > 0, "--rc must be > 0"),
        (not args.period > 0, "--period must be > 0"),
        (not args.sim_time > 0, "--sim-time must be > 0"),
        (not 0 < args.vmin <= args.vmax, "need 0 < --vmin <= --vmax"),
        (not args.pause >= 0, "--pause must be >= 0"),
        (not 0 <= args.loss < 1, "--loss must be in [0, 1)"),
    ):
        if bad:
            parser.error(why)
