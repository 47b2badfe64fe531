"""Muscles: parameters, paths round wrap cylinders on the links, the De Groote-Fregly 2016 curves and the muscle files (docs/muscles.md)."""
