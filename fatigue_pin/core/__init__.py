"""fatigue_pin.core."""
