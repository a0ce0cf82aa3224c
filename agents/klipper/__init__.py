"""Klipper's ``calibrate_shaper`` rule, re-implemented, and the baseline it gives a tuning run."""
