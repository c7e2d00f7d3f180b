"""The application: registry, runner, Monte Carlo, metrics, reports, plots, CLI."""
