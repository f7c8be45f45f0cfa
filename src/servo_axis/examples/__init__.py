"""Outside nodes to copy: plain rclpy, default QoS, nothing imported from servo_axis.

Shipped with the package (``examples/`` of a checkout is a link to this folder),
so an installed servo_axis runs them too:

* ``pd_controller``: the ``feedback`` role, a PD position controller;
* ``sine_reference``: the ``feedforward`` role, a 1 - cos reference;
* ``watch_run``: a run's state, its ``/diagnostics`` and a parameter's descriptor,
  without the ``ros2`` CLI.

    python -m servo_axis.examples.pd_controller --ros-args -r __ns:=/x
"""
