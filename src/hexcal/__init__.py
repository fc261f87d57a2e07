"""hexcal: kinematic calibration of hexapods."""
