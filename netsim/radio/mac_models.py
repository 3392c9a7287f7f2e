"""The shared media ``channel.mac`` names: ``aloha`` and ``csma`` (802.11 DCF), with their keys.

Both are the :class:`~netsim.radio.mac.Medium` (docs/radio.md, "Shared medium"), loaded
only by a run that uses one. Their keys are keys of ``[channel]``; those of ``csma`` add
the backoff's to the keys both share. ``channel.mac = "none"`` (no medium) is
:data:`netsim.radio.models.NO_MAC`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from netsim.errors import ConfigError
from netsim.params import Params, finite, non_negative, param, positive
from netsim.radio.models import MacModel

# The largest contention window: the medium keeps each robot's window and backoff as 64-bit
# integers, and draws a backoff on 0..cw (cw + 1 values); past 2^62 - 1 the window's doubling
# (2 cw + 1) or that count leaves them (a traceback of the draw, midway through the run).
MAX_CW_EXPONENT = 62


def _contention_window(v: int) -> str | None:
    # 802.11's windows are 2^k - 1: doubling keeps that form, (cw + 1) * 2 - 1.
    if 1 <= v and (v + 1) & v == 0 and v.bit_length() <= MAX_CW_EXPONENT:
        return None
    return f"must be 2^k - 1 with 1 <= k <= {MAX_CW_EXPONENT} (1, 3, 7, ..., 1023)"


# The longest CSMA interval: 802.11's are microseconds, a slow radio's (LoRa, acoustic)
# seconds; an hour is a typo, and far past it a backoff's instants overflow.
MAX_INTERVAL_S = 3600.0


def _interval(low_open: bool) -> Callable[[float], str | None]:
    """A CSMA interval's check: in ``(0`` (``low_open``) or ``[0``, ``MAX_INTERVAL_S]``, s."""
    allowed = f"must be in {'(0' if low_open else '[0'}, {MAX_INTERVAL_S:g}] (s)"

    def check(v: float) -> str | None:
        ok = 0.0 < v <= MAX_INTERVAL_S if low_open else 0.0 <= v <= MAX_INTERVAL_S
        return None if ok else allowed

    return check


# Each key's field, made anew for each parameter set that has it (a dataclass field
# belongs to one class).
def _data_rate() -> Any:
    return param(1e6, finite(positive), "data rate of every frame's payload, bit/s")


def _preamble() -> Any:
    return param(192e-6, finite(non_negative), "preamble and PHY header before every frame, s")


def _interference_range() -> Any:
    return param(
        0.0,
        finite(non_negative),
        "robots within this distance of a sender are disturbed and sense it busy, m (0: the range;"
        " log_distance: where the mean received power falls to noise_floor_dbm, or the radio's reach"
        " where that is farther)",
    )


# A level in dB(m) the medium can hold as a power in mW or a factor (10^300).
LARGEST_DB = 3000.0


def _in_mw(value: float) -> str | None:
    # The medium adds powers in mW: a level whose 10^(dB / 10) no float holds cannot be one,
    # nor one whose 10^(dB / 10) is 0 (a noise floor of 0 mW: every SINR a division by zero).
    if value < -LARGEST_DB:
        return f"must be at least {-LARGEST_DB:g} (its linear value, 10^(v / 10), must be above 0)"
    if value <= LARGEST_DB:
        return None
    return f"must be at most {LARGEST_DB:g} (its linear value, 10^(v / 10), must be a number)"


def _capture() -> Any:
    return param(10.0, finite(lambda v: non_negative(v) or _in_mw(v)), "log_distance: SINR a reception needs, dB")


def _noise_floor() -> Any:
    return param(-95.0, finite(_in_mw), "log_distance: thermal noise at the receiver, dBm")


def _queue() -> Any:
    return param(16, positive, "frames a robot's queue holds (its frame on the air included)")


@dataclass(frozen=True)
class AlohaParams(Params):
    """ALOHA's keys: the air's rate, the interference around a sender, the queue."""

    section = "channel"
    data_rate_bps: float = _data_rate()
    preamble_s: float = _preamble()
    interference_range_m: float = _interference_range()
    capture_threshold_db: float = _capture()
    noise_floor_dbm: float = _noise_floor()
    queue_frames: int = _queue()


@dataclass(frozen=True)
class CsmaParams(Params):
    """CSMA/DCF's keys: ALOHA's, and the backoff's."""

    section = "channel"
    data_rate_bps: float = _data_rate()
    preamble_s: float = _preamble()
    interference_range_m: float = _interference_range()
    capture_threshold_db: float = _capture()
    noise_floor_dbm: float = _noise_floor()
    slot_s: float = param(20e-6, _interval(True), "csma: backoff slot, s")
    difs_s: float = param(50e-6, _interval(False), "csma: idle time sensed before the backoff counts down, s")
    cw_min: int = param(31, _contention_window, "csma: initial contention window (backoff uniform on 0..cw)")
    cw_max: int = param(1023, _contention_window, "csma: largest contention window (doubles per failed unicast)")
    retry_limit: int = param(7, non_negative, "csma: retransmissions of a unicast frame before it is dropped")
    queue_frames: int = _queue()

    def check(self) -> None:
        if self.cw_max < self.cw_min:
            raise ConfigError("channel.cw_max", self.cw_max, f"must be >= channel.cw_min = {self.cw_min}")


def check_medium(params: Any, channel: Any) -> None:
    """The interference range covers the robots a frame reaches; under a radio with power,
    the noise floor leaves room for the capture threshold."""
    radio = channel.propagation_model
    if params.interference_range_m > 0:
        reach = radio.reach(channel.radio)
        if reach is None:
            largest = max(channel.range_m) if isinstance(channel.range_m, tuple) else channel.range_m
            if params.interference_range_m < largest:
                raise ConfigError(
                    "channel.interference_range_m",
                    params.interference_range_m,
                    f"must be at least the largest channel.range_m = {largest:g} (or 0: the range)",
                )
        elif params.interference_range_m < reach:
            raise ConfigError(
                "channel.interference_range_m",
                params.interference_range_m,
                f"must be at least the radio's reach = {reach:g} m under {channel.propagation} (or 0: where the mean"
                " power reaches channel.noise_floor_dbm)",
            )
    power = radio.power(channel.radio, params.noise_floor_dbm, params.capture_threshold_db)
    if power is not None:
        margin = power.sensitivity_dbm - params.noise_floor_dbm
        if margin < params.capture_threshold_db:
            # Else a frame just above the sensitivity fails on noise alone, and the
            # collision count would include those failures.
            raise ConfigError(
                "channel.noise_floor_dbm",
                params.noise_floor_dbm,
                f"must be at least channel.capture_threshold_db = {params.capture_threshold_db:g} dB below"
                f" channel.sensitivity_dbm = {power.sensitivity_dbm:g} dBm",
            )


def _airtime_s(params: Any, nbytes: int) -> float:
    return params.preamble_s + nbytes * 8.0 / params.data_rate_bps


def _tables(tables: dict) -> dict:
    from netsim.radio.mac import MEDIUM_SCHEMA, with_mac_causes

    out = with_mac_causes(tables)
    out["medium"] = MEDIUM_SCHEMA
    return out


def _build(access: str) -> Callable[[Any, Any, np.random.Generator, Any], Any]:
    def build(params: Any, channel: Any, rng: np.random.Generator, power: Any) -> Any:
        from netsim.radio import mac

        mean_power = power(params.noise_floor_dbm, params.capture_threshold_db)
        return mac.Medium(channel, params, rng, mean_power, access=getattr(mac, access))

    return build


ALOHA = MacModel(AlohaParams, _build("Aloha"), _airtime_s, _tables, check_medium)
"""``channel.mac = "aloha"``: a frame goes on the air at once (after its sender's earlier ones)."""

CSMA = MacModel(CsmaParams, _build("Csma"), _airtime_s, _tables, check_medium)
"""``channel.mac = "csma"``: 802.11 DCF's carrier sense and binary exponential backoff."""
