"""An outside extension of servo_axis: plant model ``rigid_viscous_axis``, term ``viscous_ff``."""
