"""The ``snnkart`` command line: typer commands (:mod:`snnkart.cli.main`), the rich console
that shows the app's progress (:mod:`snnkart.cli.console`) and the keyboard driver
(:mod:`snnkart.cli.play`). The only package that imports typer and rich."""

from snnkart.cli.main import app, main

__all__ = ["app", "main"]
