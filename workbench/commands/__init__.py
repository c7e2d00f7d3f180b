"""CLI command groups. Each module defines ``register(app: typer.Typer)``; ``workbench.cli``
lists the modules explicitly."""
