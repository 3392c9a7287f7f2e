"""The shared medium's hot loop (compiled or plain, :func:`netsim.compiled.load`): a
frame's end (:meth:`netsim.radio.mac.Medium._end`), one robot at a time. The tests check it
against its numpy oracle (tests/oracles/radio.py).

Its arrays are records read by field name (:class:`MediumArrays`, :class:`Leaving`,
:class:`Ends`), passed as plain tuples of their fields and named on entry, as
:mod:`netsim.radio._kernels` explains.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from netsim.compiled import jit


class MediumArrays(NamedTuple):
    """The medium's per-robot arrays a frame's end reads and updates."""

    cover: np.ndarray  # frames of other senders on the air within interference range
    transmitting: np.ndarray
    tx_seq: np.ndarray  # the robot's latest own frame
    cover_seq: np.ndarray  # the latest frame start that disturbed the robot
    busy_s: np.ndarray  # time sensed busy so far
    busy_since: np.ndarray


class Leaving(NamedTuple):
    """The frame leaving the air: frame ``seq`` of robot ``i`` at ``now``, the robots it
    disturbed, its receivers and, per receiver, whether it was lost at its start; under a
    power model (``by_power``) each receiver's SINR over the frame (dB), decided against
    ``capture_db``."""

    i: int
    seq: int
    now: float
    disturbed: np.ndarray
    rx: np.ndarray
    hd_start: np.ndarray
    col_start: np.ndarray
    by_power: bool
    sinr_db: np.ndarray
    capture_db: float


class Ends(NamedTuple):
    """Filled: per receiver, lost to half duplex, lost to a collision; the robots that
    sense the medium idle again."""

    hd: np.ndarray
    col: np.ndarray
    newly: np.ndarray


@jit(nogil=True, inline="always")
def busy_through(busy_s, busy_since, c, now):
    """Robot ``c``'s time sensed busy through ``now``, the stretch begun at ``busy_since[c]``
    counted: the one rule of the medium's busy time."""
    return busy_s[c] + (now - busy_since[c])


@jit(nogil=True, inline="always")
def senses_idle(cover, transmitting, c):
    """Robot ``c`` senses the medium idle: no other sender's frame on the air within its
    interference range, and none of its own: the one rule of an idle medium."""
    return cover[c] == 0 and not transmitting[c]


@jit(nogil=True)
def idle_among(cover, transmitting, robots, out):
    """Whether each of ``robots`` senses the medium idle (:func:`senses_idle`), into ``out``."""
    for k in range(len(robots)):
        out[k] = senses_idle(cover, transmitting, robots[k])


@jit(nogil=True)
def busy_times(medium, now, out):
    """Each robot's time sensed busy through ``now`` (:func:`busy_through` while it senses
    a frame or sends one), into ``out``. ``medium``: :class:`MediumArrays`."""
    md = MediumArrays(*medium)
    for c in range(out.shape[0]):
        if not senses_idle(md.cover, md.transmitting, c):
            out[c] = busy_through(md.busy_s, md.busy_since, c, now)
        else:
            out[c] = md.busy_s[c]


@jit(nogil=True)
def end_frame(medium, frame, out):
    """Frame ``seq`` of robot ``i`` leaves the air at ``now``: the robots it disturbed sense one
    frame less, ``hd``/``col`` (one per receiver in ``rx``) tell which receptions were lost to
    half duplex and to collisions (under a power model an SINR below the capture threshold,
    else another frame overlapping at the receiver), and the robots that sense the medium idle
    again (the disturbed, then ``i``) are written to ``newly`` with their busy time added;
    returns how many.

    ``medium``: :class:`MediumArrays`, updated; ``frame``: :class:`Leaving`; ``out``:
    :class:`Ends`, filled."""
    md = MediumArrays(*medium)
    fr = Leaving(*frame)
    en = Ends(*out)
    cover, transmitting, tx_seq, cover_seq = md.cover, md.transmitting, md.tx_seq, md.cover_seq
    busy_s, busy_since = md.busy_s, md.busy_since
    i, seq, now, disturbed, rx = fr.i, fr.seq, fr.now, fr.disturbed, fr.rx
    hd_start, col_start = fr.hd_start, fr.col_start
    by_power, sinr_db, capture_db = fr.by_power, fr.sinr_db, fr.capture_db
    hd, col, newly = en.hd, en.col, en.newly
    for k in range(len(disturbed)):
        cover[disturbed[k]] -= 1
    transmitting[i] = False
    for k in range(len(rx)):
        r = rx[k]
        lost_hd = hd_start[k] or tx_seq[r] > seq
        hd[k] = lost_hd
        if by_power:
            col[k] = (not lost_hd) and sinr_db[k] < capture_db
        else:
            col[k] = (not lost_hd) and (col_start[k] or cover_seq[r] != seq)
    m = 0
    for k in range(len(disturbed) + 1):
        c = disturbed[k] if k < len(disturbed) else i
        if senses_idle(cover, transmitting, c):
            newly[m] = c
            m += 1
    for k in range(m):
        c = newly[k]
        busy_s[c] = busy_through(busy_s, busy_since, c, now)
    return m
