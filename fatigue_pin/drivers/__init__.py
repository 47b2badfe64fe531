"""fatigue_pin.drivers."""
