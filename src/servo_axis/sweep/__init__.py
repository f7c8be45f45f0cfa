"""Studies: parameter sweeps of a scenario on dask.distributed (``python -m servo_axis sweep``).

:mod:`~servo_axis.sweep.spec` reads a study file, :mod:`~servo_axis.sweep.point`
runs one point, :mod:`~servo_axis.sweep.engine` runs them all and writes the
results. Nothing here imports rclpy.
"""
