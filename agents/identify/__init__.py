"""From the user's files to a printer description: accelerometer files, ripples and towers, added mass, and the calibration prints that make them."""
