"""The real printer: firmware dialects, config export, serial and Moonraker links, accelerometer
file readers. Imports nothing of ringtune's but ``shaping``'s plain data types."""
