"""CLI command groups. Each command module defines ``register(app: typer.Typer)``;
``workbench.cli`` lists the modules explicitly. ``bag_front_end`` and ``bag_estimators`` are
the stages of ``bag``'s command, not commands."""
