"""fatigue_pin.paper."""
