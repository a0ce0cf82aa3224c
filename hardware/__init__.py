"""The real printer: firmware dialects, config export, serial and Moonraker links, accelerometer
file readers, firmware configuration readers (Klipper printer.cfg or Moonraker, Marlin M503, RRF
config.g). Imports only ``shaping`` of ringtune's (what it sends is checked with shaping's math)."""
