"""Motors: the two-node winding-housing thermal network, motor parameters through a gear, datasheet presets and the thermal calibration (docs/motors.md)."""
