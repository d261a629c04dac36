"""Workflows behind the commands (train, evaluate, replay, pipeline, demo). They return records
and report progress through a :class:`~snnkart.app.reporter.Reporter`; they never print."""
