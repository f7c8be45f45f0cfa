"""Broken extensions of servo_axis (see the package's pyproject.toml)."""
