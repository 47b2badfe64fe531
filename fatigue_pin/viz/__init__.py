"""fatigue_pin.viz."""
