"""The shared medium's hot loop (compiled or plain, :func:`netsim.compiled.load`): a
frame's end (:meth:`netsim.radio.mac.Medium._end`), one robot at a time. The tests check it
against its numpy oracle (tests/oracles/radio.py).
"""

from __future__ import annotations

from netsim.compiled import jit


@jit(nogil=True)
def end_unit_disk(medium, frame, out):
    """Frame ``seq`` of robot ``i`` leaves the air at ``now``: the robots it disturbed sense one
    frame less, ``hd``/``col`` (one per receiver in ``rx``) tell which receptions were lost to
    half duplex and to collisions, and the robots that sense the medium idle again (the
    disturbed, then ``i``) are written to ``newly`` with their busy time added; returns how
    many.

    ``medium``: the medium's arrays, updated, ``(cover, transmitting, tx_seq, cover_seq,
    busy_s, busy_since)``; ``frame``: ``(i, seq, now, disturbed, rx, hd_start, col_start)``;
    ``out``: ``(hd, col, newly)``, filled."""
    cover, transmitting, tx_seq, cover_seq, busy_s, busy_since = medium
    i, seq, now, disturbed, rx, hd_start, col_start = frame
    hd, col, newly = out
    for k in range(len(disturbed)):
        cover[disturbed[k]] -= 1
    transmitting[i] = False
    for k in range(len(rx)):
        r = rx[k]
        lost_hd = hd_start[k] or tx_seq[r] > seq
        hd[k] = lost_hd
        col[k] = (not lost_hd) and (col_start[k] or cover_seq[r] != seq)
    m = 0
    for k in range(len(disturbed) + 1):
        c = disturbed[k] if k < len(disturbed) else i
        if cover[c] == 0 and not transmitting[c]:
            newly[m] = c
            m += 1
    for k in range(m):
        c = newly[k]
        busy_s[c] += now - busy_since[c]
    return m
