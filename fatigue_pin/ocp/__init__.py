"""fatigue_pin.ocp."""
