"""fatigue_pin.fatigue."""
