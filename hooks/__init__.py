"""Logging and analysis hooks: plugins that subscribe to the run's events (``[events] hooks``)."""
