"""The real printer: firmware dialects, config export, serial and Moonraker links, accelerometer
file readers. Imports only ``shaping`` of ringtune's (what it sends is checked with shaping's math)."""
