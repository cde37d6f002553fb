"""Procedural MJCF models: the guidewire, the robot driver with its sheath, and the scene."""
