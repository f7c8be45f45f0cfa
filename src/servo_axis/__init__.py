"""servo_axis: a ROS 2 (Jazzy) emulation of a machine-tool servo axis and its controllers."""

__version__ = "0.1.0"
