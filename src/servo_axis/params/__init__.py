"""Parameters: schemas, scenario files, the extension registries, factories and the resolver.

:mod:`~servo_axis.params.param` (``Param``, the checks), :mod:`~servo_axis.params.schemas`
(the nodes' keys), :mod:`~servo_axis.params.registry` (the entry points of the
extensions), :mod:`~servo_axis.params.scenario` (loading a scenario file),
:mod:`~servo_axis.params.factories` (checked values -> core objects),
:mod:`~servo_axis.params.resolve` (a scenario -> each node's values) and
:mod:`~servo_axis.params.names` (ROS names and domain ids). Nothing here imports rclpy.
"""
