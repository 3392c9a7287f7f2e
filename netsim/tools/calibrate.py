"""``netsim calibrate LOG``: the log-distance channel fitted to a site's logged frames.

The log is a CSV or Parquet file, one row per frame, with ``t_s``, ``src``, ``dst``, the
power ``rssi_dbm`` (or ``rx_power_dbm``) and either ``distance_m`` or both ends' positions
(``src_x_m``, ``src_y_m``, ``dst_x_m``, ``dst_y_m``). A row whose power is empty is a frame
sent but not received; with a ``received`` column (as in a run's ``receptions.parquet``),
the rows where it is false are those, whatever their power column holds. The statistics are
in :mod:`netsim.tools.channel_fit`; this module reads and checks the log, runs the fits and
writes the ``[channel]`` fragment.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from netsim.config import from_dict
from netsim.errors import NetsimInputError
from netsim.geometry import distances_m
from netsim.radio.mac import MAC_DROP_CAUSES
from netsim.radio.propagation import LogDistanceParams
from netsim.tools import channel_fit as cf

POSITIONS = ("src_x_m", "src_y_m", "dst_x_m", "dst_y_m")
POWER_COLUMNS = ("rssi_dbm", "rx_power_dbm")
# Below this spread about the law (dB) a log has no shadowing to fit: a radio's RSSI is
# quantised far more coarsely, so only a log of a channel without shadowing comes here.
NO_SPREAD_DB = 1e-6
MIN_FRAMES = 30
MIN_PAIRS = 5


@dataclass(frozen=True)
class Calibration:
    """What ``netsim calibrate`` found."""

    fit: cf.ChannelFit
    naive: cf.ChannelFit
    decorrelation: cf.Decorrelation
    sensitivity_dbm: float
    sensitivity_given: bool
    tx_power_dbm: float
    reference_distance_m: float
    frames: int
    received: int
    pairs: int
    robots: int
    lost_measured: int = 0  # of ``received``: frames lost after the radio heard them
    # Frames lost so without a logged power: at or above the sensitivity in a censored fit;
    # a truncated fit, which takes every frame as clearing it, has nothing to learn from them.
    lost_unmeasured: int = 0
    # Frames not received whose logged power clears the sensitivity: read as below it all the
    # same; of them, those whose cause says below it (out_of_range).
    unread_above: int = 0
    unread_out_of_range: int = 0
    left_out: int = 0  # rows that tell nothing of the channel (never sent, ...)
    shadowing_draws: float | None = None  # independent draws of the shadowing (None: no travel)
    design: cf.Design | None = None  # the rows fitted (for the figure, calibrate_figure)

    def law_dbm(self, fit: cf.ChannelFit, distance_m: np.ndarray) -> np.ndarray:
        """The mean power ``fit`` gives at each distance, through no wall."""
        n = len(distance_m)
        walls = None if fit.wall_loss_db is None else np.zeros(n)
        g = distance_term_db(distance_m, self.reference_distance_m)
        return fit.mean_dbm(cf.Design(np.full(n, np.nan), g, walls, np.zeros(n, np.int64), self.tx_power_dbm))

    def channel(self) -> dict:
        """The ``[channel]`` keys, as ``netsim run`` reads them."""
        keys = {
            "propagation": "log_distance",
            "tx_power_dbm": self.tx_power_dbm,
            "reference_distance_m": self.reference_distance_m,
            "reference_loss_db": self.fit.reference_loss_db.value,
            "path_loss_exponent": self.fit.path_loss_exponent.value,
            "sensitivity_dbm": self.sensitivity_dbm,
            "shadowing_sigma_db": self.fit.shadowing_sigma_db.value,
        }
        if self.decorrelation.estimate is not None:
            keys["shadowing_decorrelation_m"] = self.decorrelation.estimate.value
        if self.fit.wall_loss_db is not None:
            keys["wall_loss_db"] = self.fit.wall_loss_db.value
        return keys


def read_log(path: Path) -> pd.DataFrame:
    """The log as a table; a missing or unreadable file is a :class:`NetsimInputError`."""
    if not path.exists():
        raise NetsimInputError(f"{path}: no such file")
    if path.is_dir():
        raise NetsimInputError(f"{path}: is a directory; give a CSV or Parquet log of frames")
    suffix = path.suffix.lower()
    try:
        if suffix == ".csv":
            with path.open(newline="") as f:
                _refuse_repeated(next(csv.reader(f), []), path)
            return pd.read_csv(path)
        if suffix in (".parquet", ".pq"):
            import pyarrow.parquet as pq

            _refuse_repeated(pq.read_schema(path).names, path)
            return pd.read_parquet(path)
    except pd.errors.EmptyDataError:
        raise NetsimInputError(f"{path}: is empty (no header, no frames)") from None
    except (ValueError, OSError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        kind = "CSV" if suffix == ".csv" else "Parquet"
        raise NetsimInputError(f"{path}: cannot be read as {kind} ({first})") from None
    raise NetsimInputError(f"{path}: unknown format {suffix or '(no suffix)'!r}; give a .csv or .parquet log")


def _refuse_repeated(names: list[str], path: Path) -> None:
    """A column named twice is refused: which of the two a fit read would be a guess."""
    seen: set[str] = set()
    for name in (n.strip() for n in names):
        if name in seen:
            raise NetsimInputError(f"{path}: column {name} appears more than once; give each column once")
        seen.add(name)


def _shown(value: object) -> str:
    """A cell as a user wrote it: ``'abc'`` for text, ``nan`` or ``inf`` for a number."""
    return repr(str(value)) if isinstance(value, str) else str(value.item() if isinstance(value, np.generic) else value)


def _numbers(log: pd.DataFrame, column: str, where: str, missing_ok: bool = False) -> np.ndarray:
    """A column as floats; a cell that is not a number (or missing, unless allowed) is refused."""
    raw = log[column]
    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    bad = (np.isnan(values) & raw.notna().to_numpy()) | np.isinf(values)
    if not missing_ok:
        bad |= np.isnan(values)
    _refuse_cells(bad, raw, where, "is not a finite number")
    return values


def _such_rows(count: int) -> str:
    return f"{count:,} such row{'s' if count > 1 else ''}"


def _refuse_cells(bad: np.ndarray, column: pd.Series, where: str, why: str) -> None:
    """Refuse a log whose ``column`` has ``bad`` cells, in one line naming the first."""
    if bad.any():
        i, count = int(np.flatnonzero(bad)[0]), int(bad.sum())
        raise NetsimInputError(
            f"{where}: column {column.name} row {i + 1}: {_shown(column.iloc[i])} {why} ({_such_rows(count)})"
        )


@dataclass(frozen=True)
class Frames:
    """The checked log: power (NaN: not received), distance, positions (or None), pair ids."""

    t_s: np.ndarray
    power_dbm: np.ndarray
    distance_m: np.ndarray
    positions: np.ndarray | None  # (rows, 4): src x, y, dst x, y
    src: np.ndarray  # robot index
    dst: np.ndarray
    robots: int
    lost_measured: int = 0  # rows lost after the radio heard them, read at their power
    lost_unmeasured: int = 0  # rows lost so without a power (``unmeasured``)
    unmeasured: np.ndarray | None = None  # bool per row: lost after the radio heard it, no power logged
    # Per row: a power logged beside received = false (and no cause that counts it), NaN otherwise.
    unread_dbm: np.ndarray | None = None
    caused: np.ndarray | None = None  # bool per row: the log gives a cause
    left_out: int = 0  # rows that tell nothing of the channel (NEVER_SENT, NO_TELLING), not in the arrays

    def rows(self, keep: np.ndarray) -> Frames:
        """These frames but for the rows ``keep`` leaves out."""

        def cut(a):
            return None if a is None else a[keep]

        names = ("t_s", "power_dbm", "distance_m", "positions", "src", "dst", "unmeasured", "unread_dbm", "caused")
        return dataclasses.replace(self, **{name: cut(getattr(self, name)) for name in names})

    @property
    def pair(self) -> np.ndarray:
        lo, hi = np.minimum(self.src, self.dst), np.maximum(self.src, self.dst)
        return lo * self.robots + hi

    def travel_m(self) -> np.ndarray:
        """Each row's pair travel: both robots' path lengths up to the row's time, each robot's
        path the polyline through every position the log gives of it (src or dst end)."""
        n = len(self.t_s)
        robot = np.r_[self.src, self.dst]
        t = np.r_[self.t_s, self.t_s]
        xy = np.r_[self.positions[:, :2], self.positions[:, 2:]]
        order = np.lexsort((t, robot))
        step = np.zeros(2 * n)
        same = robot[order[1:]] == robot[order[:-1]]
        step[1:] = np.where(same, distances_m(xy[order[:-1]], xy[order[1:]]), 0.0)
        # Cumulative per robot: the running sum restarted at each robot's first observation.
        run = np.cumsum(step)
        first = np.r_[True, ~same]
        run -= np.maximum.accumulate(np.where(first, run, -np.inf))
        odo = np.empty(2 * n)
        odo[order] = run
        return odo[:n] + odo[n:]


# The cause a run's receptions.parquet gives a frame its radio did not hear: the one cause
# that says the power fell below the sensitivity (or a wall or the range stopped it). Every
# other cause the channel and its medium give drops a frame the radio heard.
BELOW_SENSITIVITY = "out_of_range"
# Causes of a log's rows that tell nothing of the channel, left out: a frame never sent (a
# full queue), and a unicast whose every try failed with no power logged (out of range or
# lost after, no telling which).
NEVER_SENT = "queue_full"
NO_TELLING = "retry_limit"


def _causes(log: pd.DataFrame, where: str) -> np.ndarray:
    """The ``cause`` column as the channel spells its causes ("" where none is given);
    a cause it does not know is refused."""
    # As plain values: a categorical column (pandas' or a dictionary-encoded Parquet column)
    # takes no "" it does not list.
    cause = log["cause"].astype(object)
    words = cause.where(cause.notna(), "").astype(str).str.strip().str.lower()
    words = words.str.replace(" ", "_").str.replace("-", "_").to_numpy()
    known = f"is not a cause of the channel's ({', '.join(MAC_DROP_CAUSES)}; empty for a frame received)"
    _refuse_cells((words != "") & ~np.isin(words, MAC_DROP_CAUSES), cause, where, known)
    return words


def check_log(log: pd.DataFrame, where: str, need_positions: bool) -> Frames:
    """The log's columns checked and read: one line naming the problem otherwise."""
    # A header written by hand ("t_s, src, dst") names its columns with the spaces around.
    log = log.rename(columns=lambda c: c.strip() if isinstance(c, str) else c)
    cols = set(log.columns)
    power = next((c for c in POWER_COLUMNS if c in cols), None)
    missing = [c for c in ("t_s", "src", "dst") if c not in cols] + ([] if power else ["rssi_dbm"])
    has_positions = all(c in cols for c in POSITIONS)
    if need_positions and not has_positions:
        missing += [c for c in POSITIONS if c not in cols]
    elif not has_positions and "distance_m" not in cols:
        missing.append(f"distance_m (or {', '.join(POSITIONS)})")
    if missing:
        # One column whose name holds another separator: a CSV file written with it.
        names = [str(c) for c in log.columns]
        split = next((sep for sep in (";", "\t", "|") if len(names) == 1 and sep in names[0]), None)
        hint = f"; its header is one column holding {split!r}: a CSV log is separated by commas" if split else ""
        raise NetsimInputError(
            f"{where}: lacks the column{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
            f"(a log needs t_s, src, dst, rssi_dbm (or rx_power_dbm) and distance_m or {', '.join(POSITIONS)}"
            f"{'; --map needs the positions' if need_positions else ''}{hint})"
        )
    if len(log) == 0:
        raise NetsimInputError(f"{where}: has no frames (only a header)")
    t_s = _numbers(log, "t_s", where)
    power_dbm = _numbers(log, power, where, missing_ok=True)
    if np.isnan(power_dbm).all():
        raise NetsimInputError(
            f"{where}: column {power} is empty in every row: no frame's power to fit (a run records one only "
            "under channel.propagation = log_distance; under the unit disk rx_power_dbm is NaN)"
        )
    lost_measured = lost_unmeasured = 0
    unmeasured = np.zeros(len(log), bool)
    unread_dbm = None
    # Rows that tell nothing of the channel are left out (NEVER_SENT, NO_TELLING).
    keep = np.ones(len(log), bool)
    caused = np.zeros(len(log), bool)
    if "received" in cols:
        words = {"true": True, "false": False}
        received = log["received"].map(lambda v: words.get(v.lower(), v) if isinstance(v, str) else v)
        if received.isna().any() or not set(received.unique()) <= {True, False}:
            raise NetsimInputError(f"{where}: column received must hold true or false in every row")
        received = received.astype(bool).to_numpy()
        lacking = received & np.isnan(power_dbm)
        if lacking.any():
            i = int(np.flatnonzero(lacking)[0])
            raise NetsimInputError(f"{where}: row {i + 1} is received but its {power} is empty")
        if "cause" in cols:
            # A frame lost after the radio heard it cleared the sensitivity: its power is a
            # measurement like a received frame's. Read as censored below the sensitivity it
            # would bias the fit toward more loss; one without a logged power is known to be
            # at or above it (censored from above).
            words = _causes(log, where)
            contradicts = received & (words != "")
            if contradicts.any():
                i = int(np.flatnonzero(contradicts)[0])
                raise NetsimInputError(
                    f"{where}: row {i + 1} is received but gives the cause {words[i]!r} (a cause says why a frame "
                    f"was lost; empty for a frame received) ({_such_rows(int(contradicts.sum()))})"
                )
            keep = ~((words == NEVER_SENT) | ((words == NO_TELLING) & np.isnan(power_dbm)))
            caused = words != ""
            lost = ~received & caused & (words != BELOW_SENSITIVITY) & keep
            unmeasured = lost & np.isnan(power_dbm)
            lost &= ~unmeasured
            lost_measured, lost_unmeasured = int(lost.sum()), int(unmeasured.sum())
            received = received | lost
        unread_dbm = np.where(received, np.nan, power_dbm)
        power_dbm = np.where(received, power_dbm, np.nan)
    for c in ("src", "dst"):
        if log[c].isna().any():
            i = int(np.flatnonzero(log[c].isna().to_numpy())[0])
            raise NetsimInputError(f"{where}: column {c} row {i + 1} is empty (every frame needs both robots)")
    ids, names = pd.factorize(pd.concat([log["src"], log["dst"]], ignore_index=True))
    src, dst = ids[: len(log)].astype(np.int64), ids[len(log) :].astype(np.int64)
    if (src == dst).any():
        i = int(np.flatnonzero(src == dst)[0])
        raise NetsimInputError(
            f"{where}: row {i + 1} has src = dst = {_shown(log['src'].iloc[i])}: a frame goes from one robot to another"
        )
    positions = None
    if has_positions:
        positions = np.column_stack([_numbers(log, c, where) for c in POSITIONS])
    # distance_m where the log gives it (a run's on a torus is the nearest image's), else
    # the straight distance between the two ends' positions.
    if "distance_m" in cols:
        distance = _numbers(log, "distance_m", where)
        what = "distance_m"
    else:
        distance = distances_m(positions[:, 0:2], positions[:, 2:4])
        what = "the distance between the two ends' positions"
    bad = ~(distance > 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise NetsimInputError(
            f"{where}: row {i + 1}: {what} is {distance[i]:g}; every distance must be > 0 m "
            f"({_such_rows(int(bad.sum()))})"
        )
    frames = Frames(
        t_s,
        power_dbm,
        distance,
        positions,
        src,
        dst,
        len(names),
        lost_measured,
        lost_unmeasured,
        unmeasured,
        unread_dbm,
        caused,
        int((~keep).sum()),
    )
    return frames if keep.all() else frames.rows(keep)


def check_sensitivity(power_dbm: np.ndarray, sensitivity_dbm: float | None, where: str) -> None:
    """A given sensitivity must lie at or below every logged power: a frame below it is
    never received, so a log holding one contradicts it."""
    if sensitivity_dbm is None:
        return
    seen = power_dbm[~np.isnan(power_dbm)]
    below = seen < sensitivity_dbm
    if below.all():
        raise NetsimInputError(
            f"--sensitivity-dbm {sensitivity_dbm:g}: above every logged power (the strongest is {seen.max():g} dBm); "
            "no frame below the sensitivity is received"
        )
    if below.any():
        raise NetsimInputError(
            f"--sensitivity-dbm {sensitivity_dbm:g}: {int(below.sum()):,} frames of {where} were received below it "
            f"(the weakest at {seen.min():g} dBm); give at most that, or leave it out to estimate it"
        )


class CalibrationWarning(UserWarning):
    """A log that the fit takes, but that may not be what the user meant."""


def check_tx_power(power_dbm: np.ndarray, tx_power_dbm: float, where: str) -> None:
    """Warn of logged powers above the transmit power: a path loss below 0 dB, which only
    a favourable shadowing within the first metres gives (netsim's own channel can, its
    shadowing clipped at 4 sigma); many of them, or far above, are a log in another unit
    or a transmit power that is not the radio's, and they move the fit."""
    above = power_dbm > tx_power_dbm
    if above.any():
        count = int(above.sum())
        warnings.warn(
            f"{count:,} frame{'s' if count > 1 else ''} of {where} logged above --tx-power-dbm {tx_power_dbm:g} "
            f"(the strongest at {np.nanmax(power_dbm):g} dBm): a path loss below 0 dB; "
            "if the transmit power is not the radio's, give it",
            CalibrationWarning,
            stacklevel=2,
        )


def distance_term_db(distance_m: np.ndarray, reference_distance_m: float) -> np.ndarray:
    """The law's distance term, ``10 log10(max(d, d0) / d0)``: its loss with exponent 1 and
    none at ``d0``."""
    term = LogDistanceParams(reference_distance_m=reference_distance_m, reference_loss_db=0.0, path_loss_exponent=1.0)
    return term.path_loss_db(distance_m)


def calibrate_frames(
    frames: Frames,
    sensitivity_dbm: float | None = None,
    tx_power_dbm: float = LogDistanceParams.tx_power_dbm,
    reference_distance_m: float = LogDistanceParams.reference_distance_m,
    walls: np.ndarray | None = None,
    where: str = "the log",
) -> Calibration:
    """Fit the channel to checked frames (see :mod:`netsim.tools.channel_fit`)."""
    seen = ~np.isnan(frames.power_dbm)
    pair = frames.pair
    received_pairs = len(np.unique(pair[seen]))
    if seen.sum() < MIN_FRAMES or received_pairs < MIN_PAIRS:
        raise NetsimInputError(
            f"{where}: too few frames to fit: {int(seen.sum()):,} received frames from {received_pairs} pairs; "
            f"need at least {MIN_FRAMES} from {MIN_PAIRS} pairs of robots"
        )
    check_sensitivity(frames.power_dbm, sensitivity_dbm, where)
    given = sensitivity_dbm is not None
    s = float(sensitivity_dbm) if given else float(frames.power_dbm[seen].min())
    # The law's distance term, 10 log10(max(d, d0) / d0): its loss with exponent 1 and none at d0.
    g = distance_term_db(frames.distance_m, reference_distance_m)
    if np.ptp(g[seen]) < 1e-9:
        raise NetsimInputError(
            f"{where}: every received frame is at the same distance (or within "
            f"--reference-distance-m {reference_distance_m:g} m): the path-loss exponent cannot be fitted"
        )
    if walls is not None and np.ptp(walls[seen]) == 0:
        raise NetsimInputError(
            f"{where}: every received frame crosses {int(walls[seen][0])} walls of the map: "
            "the wall loss cannot be fitted apart from the reference loss"
        )
    above = np.zeros(len(seen), bool) if frames.unmeasured is None else frames.unmeasured
    design = cf.Design(frames.power_dbm, g, walls, pair, float(tx_power_dbm), above)
    censored = bool((~seen & ~above).any())
    try:
        naive = cf.fit_naive(design)
        if naive.shadowing_sigma_db.value < NO_SPREAD_DB:
            raise cf.FitError(
                f"every received frame's power lies on the law (reference_loss_db {naive.reference_loss_db.value:.6g}, "
                f"path_loss_exponent {naive.path_loss_exponent.value:.6g}) within {NO_SPREAD_DB:g} dB: "
                "no shadowing to fit a spread or intervals by (a log of a channel without shadowing?)"
            )
        fit = cf.fit_censored(design, s) if censored else cf.fit_truncated(design, s)
    except cf.FitError as exc:
        raise NetsimInputError(f"{where}: {exc}") from None
    if frames.positions is None:
        decorrelation = cf.Decorrelation(
            None, 0, 0, "needs each pair's travel, so both ends' positions (src_x_m, src_y_m, dst_x_m, dst_y_m)"
        )
    else:
        sigma = fit.shadowing_sigma_db.value
        mean = fit.mean_dbm(design)
        clear = seen & (mean - s > cf.CLEAR_SIGMAS * sigma)
        decorrelation = cf.fit_decorrelation(frames.power_dbm - mean, frames.travel_m(), pair, clear, sigma)
    draws = None
    if decorrelation.estimate is not None:
        draws = shadowing_draws(frames.travel_m()[seen], pair[seen], decorrelation.estimate.value)
    result = Calibration(
        fit,
        naive,
        decorrelation,
        s,
        given,
        float(tx_power_dbm),
        float(reference_distance_m),
        len(frames.t_s),
        int(seen.sum()),
        len(np.unique(pair)),
        frames.robots,
        frames.lost_measured,
        frames.lost_unmeasured,
        *_unread_above(frames, s),
        frames.left_out,
        draws,
        design,
    )
    check_channel(result)
    # Warned only of a log that fits: a refused one is one line, the refusal's.
    check_tx_power(frames.power_dbm, tx_power_dbm, where)
    return result


# Below this many independent draws of the shadowing, the intervals hold the truth less
# often than 95 % (tests.calibration_logs --coverage: docs/radio.md, "Intervals").
SHORT_LOG_DRAWS = 3000


def shadowing_draws(travel_m: np.ndarray, pair: np.ndarray, decorrelation_m: float) -> float:
    """About how many independent draws of the shadowing the frames hold: each pair
    ``1 + travel / d_corr``, its travel over the log against the decorrelation distance.
    With few of them the intervals are too narrow (:data:`SHORT_LOG_DRAWS`)."""
    order = np.argsort(pair, kind="stable")
    starts = np.flatnonzero(np.r_[True, pair[order][1:] != pair[order][:-1]])
    spans = np.maximum.reduceat(travel_m[order], starts) - np.minimum.reduceat(travel_m[order], starts)
    return float(np.sum(1.0 + spans / decorrelation_m))


def _unread_above(frames: Frames, sensitivity_dbm: float) -> tuple[int, int]:
    """Rows marked not received whose logged power clears the sensitivity: without a cause,
    and with the cause ``out_of_range``."""
    if frames.unread_dbm is None:
        return 0, 0
    above = frames.unread_dbm >= sensitivity_dbm
    caused = np.zeros(len(above), bool) if frames.caused is None else frames.caused
    return int((above & ~caused).sum()), int((above & caused).sum())


def calibrate_frame(log: pd.DataFrame, sensitivity_dbm: float | None = None, where: str = "the log", **kw):
    """:func:`calibrate_frames` of a table in the log's format."""
    return calibrate_frames(check_log(log, where, need_positions=False), sensitivity_dbm, where=where, **kw)


def _cell(e: cf.Estimate | None) -> str:
    return "-" if e is None else f"{e.value:.4g} [{e.low:.4g}, {e.high:.4g}]"


def report(c: Calibration, where: str) -> str:
    """The printed table: each estimate with its 95 % interval, the naive fit beside."""
    fit, naive = c.fit, c.naive
    lost = c.lost_measured + c.lost_unmeasured
    below = c.frames - c.received - c.lost_unmeasured
    heard = f"{c.received - c.lost_measured:,} received"
    heard += f", {lost:,} lost after the radio heard them" if lost else ""
    heard += f", {below:,} not received" if below else ""
    lines = [
        f"netsim calibrate: {where}: {c.frames:,} frames ({heard}) between {c.pairs:,} pairs of {c.robots:,} robots"
    ]
    if c.left_out:
        lines.append(
            f"the {c.left_out:,} frames that tell nothing of the channel are left out ({NEVER_SENT}: never sent; "
            f"{NO_TELLING} without a power: out of range or lost after, no telling which)"
        )
    if c.lost_measured:
        lines.append(
            f"the {c.lost_measured:,} frames lost after the radio heard them (to the loss model, a collision, ...) "
            "cleared the sensitivity: they count at their logged power"
        )
    if c.lost_unmeasured and fit.likelihood == "censored":
        lines.append(
            f"the {c.lost_unmeasured:,} frames lost after the radio heard them without a logged power count as "
            "at or above the sensitivity"
        )
    elif c.lost_unmeasured:
        lines.append(
            f"the {c.lost_unmeasured:,} frames lost after the radio heard them without a logged power are left out: "
            "a truncated fit takes every frame as clearing the sensitivity, so they tell it nothing"
        )
    if c.unread_above:
        lines.append(
            f"note: {c.unread_above:,} frames marked not received log a power at or above the sensitivity; they are "
            "read as below it all the same (a cause column saying why each was lost lets it count at its power)"
        )
    if c.unread_out_of_range:
        lines.append(
            f"note: {c.unread_out_of_range:,} frames of cause {BELOW_SENSITIVITY} log a power at or above the "
            "sensitivity; they are read as below it all the same (is the sensitivity given below the radio's?)"
        )
    if fit.likelihood == "censored":
        lines.append(
            f"likelihood: censored (Tobit): {c.frames - c.received - c.lost_unmeasured:,} frames sent but not "
            "received count as below the sensitivity"
        )
    else:
        lines.append("likelihood: truncated at the sensitivity (the log lists no frame that fell short of it)")
    if c.sensitivity_given:
        lines.append(f"sensitivity_dbm: {c.sensitivity_dbm:g} (given)")
    else:
        lines.append(
            f"sensitivity_dbm: {c.sensitivity_dbm:.4g} (estimated: the weakest power of a received frame, the "
            "maximum-likelihood estimate of the power below which no frame arrives; give --sensitivity-dbm if the "
            "radio's is known)"
        )
    lines.append(f"tx_power_dbm: {c.tx_power_dbm:g}, reference_distance_m: {c.reference_distance_m:g} (used as given)")
    rows = [
        ("reference_loss_db", fit.reference_loss_db, naive.reference_loss_db),
        ("path_loss_exponent", fit.path_loss_exponent, naive.path_loss_exponent),
    ]
    if fit.wall_loss_db is not None:
        rows.append(("wall_loss_db", fit.wall_loss_db, naive.wall_loss_db))
    rows += [
        ("shadowing_sigma_db", fit.shadowing_sigma_db, naive.shadowing_sigma_db),
        ("shadowing_decorrelation_m", c.decorrelation.estimate, None),
    ]
    head = f"  {'key':<26}  {'maximum likelihood [95 % interval]':<36}  naive least squares"
    lines.append(head)
    for name, e, n in rows:
        lines.append(f"  {name:<26}  {_cell(e):<36}  {'-' if n is None else f'{n.value:.4g}'}")
    lines.append(
        "intervals: 95 %, cluster-robust (sandwich) with the pair as cluster: a pair's frames share its shadowing"
    )
    if c.shadowing_draws is not None and c.shadowing_draws < SHORT_LOG_DRAWS:
        lines.append(
            f"  short log: about {c.shadowing_draws:,.0f} independent draws of the shadowing (each pair 1 + its "
            f"travel / d_corr), under {SHORT_LOG_DRAWS:,}: the intervals hold the truth less often than 95 % "
            '(docs/radio.md, "Intervals"); log for longer'
        )
    elif c.shadowing_draws is None and c.pairs < SHORT_LOG_DRAWS:
        # Without d_corr the draws cannot be counted; each pair is one at least.
        lines.append(
            f"  short log?: the independent draws of the shadowing are not counted without d_corr; at least "
            f"{c.pairs:,} (one a pair), under {SHORT_LOG_DRAWS:,}: if the robots moved little against d_corr, "
            'the intervals hold the truth less often than 95 % (docs/radio.md, "Intervals")'
        )
    d = c.decorrelation
    if d.estimate is None:
        lines.append(f"shadowing_decorrelation_m: not estimated ({d.reason}); left out of the fragment")
    else:
        lines.append(
            f"shadowing_decorrelation_m: from {d.steps:,} steps between consecutive frames of {d.pairs:,} pairs "
            f"whose predicted power is over {cf.CLEAR_SIGMAS:g} sigma above the sensitivity"
        )
    lines.append("naive least squares: through the received frames as if none were lost; biased (see docs/radio.md)")
    return "\n".join(lines)


def _printable(text: str) -> str:
    """``text`` with its control characters escaped: a TOML comment may hold none but tab."""
    return "".join(ch if ch == "\t" or (ch >= " " and ch != "\x7f") else f"\\x{ord(ch):02x}" for ch in text)


def toml_fragment(c: Calibration, where: str, world_map: str | None = None) -> str:
    """The ``[channel]`` keys fitted; with ``world_map`` (the map the walls were counted on)
    a ``[world]`` on that map too, without which a run ignores the wall loss."""
    lines = [
        f"# netsim calibrate {_printable(where)}: {c.received + c.lost_unmeasured:,} frames the radio heard of "
        f"{c.pairs:,} pairs, {c.fit.likelihood} likelihood",
    ]
    if world_map is not None:
        lines += [
            "# wall_loss_db is a loss per wall of this map: a run without it ignores that key",
            "[world]",
            f"map = {json.dumps(world_map, ensure_ascii=False)}",  # a TOML basic string too
            'bounds_m = "map"',
        ]
    lines.append("[channel]")
    for k, v in c.channel().items():
        lines.append(f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {float(v)!r}")
    return "\n".join(lines) + "\n"


def fragment_map(given: str) -> str:
    """How the fragment names ``--map``'s map: an example by its name, a file by its
    absolute path (the fragment may be written, and run, elsewhere)."""
    from netsim.world.maps import EXAMPLES

    return given if given in EXAMPLES else str(Path(given).resolve())


def check_channel(c: Calibration) -> None:
    """The fitted channel must be one ``netsim run`` accepts as it is: its keys' bounds and
    the rules across keys, on the built-in scenario the fragment alone runs on."""
    try:
        with warnings.catch_warnings():
            # A fitted wall loss without a map is warned of by a run, not a fault of the fit.
            warnings.simplefilter("ignore")
            from_dict({"channel": c.channel()})
    except NetsimInputError as exc:
        unit = ""
        logged = c.design.y_dbm[~np.isnan(c.design.y_dbm)] if c.design is not None else np.empty(0)
        if len(logged) and logged.min() >= 0.0:
            # A receiver hears above 1 mW only metres from the sender: a whole log so is in
            # another unit (mW or W), the likeliest cause of a fit out of bounds.
            unit = f"; every logged power is at or above 0 dBm (the weakest {logged.min():g}): a log in mW, not dBm?"
        raise NetsimInputError(f"the fitted channel is not one netsim runs: {exc}{unit}") from None


def _check_flag(flag: str, value: float | None, ok, allowed: str) -> None:
    if value is not None and not (math.isfinite(value) and ok(value)):
        raise NetsimInputError(f"{flag} {value:g}: {allowed}")


def command(args, draw: Callable[[Calibration, str, str], object] | None = None) -> int:
    """``netsim calibrate`` (:mod:`netsim.tools.cli` checks ``--out`` and ``--plot`` first);
    ``draw(calibration, path, log)`` draws ``--plot``'s figure (given with ``--plot``)."""
    _check_flag("--sensitivity-dbm", args.sensitivity_dbm, lambda v: -200 <= v <= 0, "must be in [-200, 0] dBm")
    _check_flag("--tx-power-dbm", args.tx_power_dbm, lambda v: -60 <= v <= 60, "must be in [-60, 60] dBm")
    _check_flag("--reference-distance-m", args.reference_distance_m, lambda v: 0 < v <= 1e6, "must be in (0, 1e6] m")
    path = Path(args.log)
    log = read_log(path)
    frames = check_log(log, str(path), need_positions=args.map is not None)
    walls = None
    if args.map is not None:
        from netsim.world.los import walls_crossed
        from netsim.world.maps import load_map

        occupancy = load_map(args.map, "--map")
        src, dst = frames.positions[:, :2], frames.positions[:, 2:]
        off = ~(occupancy.contains(src) & occupancy.contains(dst))
        if off.any():
            # A log in another frame than the map's (odometry against the map, say) would
            # count walls that are not between the robots.
            x0, x1, y0, y1 = occupancy.extent_m
            first = int(np.flatnonzero(off)[0])
            raise NetsimInputError(
                f"{path}: {int(off.sum()):,} of {len(off):,} frames have an end off the map {args.map} "
                f"(x {x0:g} to {x1:g} m, y {y0:g} to {y1:g} m), the first from ({src[first, 0]:g}, "
                f"{src[first, 1]:g}) to ({dst[first, 0]:g}, {dst[first, 1]:g}): "
                "the positions must be in the map's frame"
            )
        walls = walls_crossed(occupancy, src, dst).astype(float)
    result = calibrate_frames(
        frames, args.sensitivity_dbm, args.tx_power_dbm, args.reference_distance_m, walls, where=str(path)
    )
    print(report(result, str(path)))
    text = toml_fragment(result, str(path), None if walls is None else fragment_map(args.map))
    if draw is not None:
        draw(result, args.plot, str(path))
        print(f"wrote {args.plot}")
    if args.out is None:
        print("\n" + text, end="")
        return 0
    out = Path(args.out)
    tmp = out.with_name(f".{out.name}.tmp")
    try:
        tmp.write_text(text)
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    print(f"wrote {out} (run it: netsim run {out})")
    return 0
