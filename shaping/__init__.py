"""What the firmware does to motion: shapers, trajectory shaping, G-code reader, planner and
frequency limit. Imports nothing of ringtune's but ``hardware``'s plain data types."""
