"""The tuning study behind ``ringtune tune``: search space, Optuna study, Pareto front and choice, baselines, the job's accelerations, storage, the report and its plots."""
