"""Who decides: the Optuna study, PPO, baselines (Klipper's rule, grid), reports, plots, the CLI."""

__version__ = "0.1.0"
