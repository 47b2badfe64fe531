"""fatigue_pin.robot."""
