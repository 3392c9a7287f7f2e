"""Mobility models for netsim: how robots move. Each model is a plugin (docs/plugins.md)."""
