"""fatigue_pin.io."""
