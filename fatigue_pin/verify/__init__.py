"""fatigue_pin.verify."""
