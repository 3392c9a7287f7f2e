"""``protocol.model = "none"``: no messages at all, for runs of mobility alone. Its tables
say so: no Ack sent (``acks``), nobody takes a role (``roles``, empty)."""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd
from netsim.protocols.ack import ACKS_SCHEMA, ack_figures
from netsim.protocols.roles import ROLES_SCHEMA, declare_roles

from netsim.params import NoParams
from netsim.plugins import Parts, PluginSpec


class Silent:
    """The protocol that sends nothing."""

    def summary(self, frames: Mapping[str, pd.DataFrame], duration_s: float) -> dict:
        return ack_figures(frames)


def build(params: NoParams, parts: Parts) -> Silent:
    declare_roles(parts.trace)
    channel = parts.channel
    parts.trace.add_frame("acks", lambda: channel.frame("ack"))
    return Silent()


PLUGIN = PluginSpec(Params=NoParams, build=build, tables={"roles": ROLES_SCHEMA, "acks": ACKS_SCHEMA})
