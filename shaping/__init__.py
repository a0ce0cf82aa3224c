"""What the firmware does to motion: shapers, firmware records, trajectory shaping, G-code reader,
planner and frequency limit. Imports nothing of ringtune's (the bottom layer)."""
