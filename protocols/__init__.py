"""Protocols for netsim: the Ack beacon and neighbour tables (and what builds on them)."""
