"""fatigue_pin.sweep."""
