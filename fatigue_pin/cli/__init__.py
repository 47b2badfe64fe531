from fatigue_pin.cli.main import main

__all__ = ["main"]
