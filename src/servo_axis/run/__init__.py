"""Running a scenario: from the scenario file to a recorded, summarised run.

* :mod:`servo_axis.run.plan`: the run's parameter file (handshake counts from
  the table of topics, what the recorder records, what the learning unit
  copies, simulated time);
* :mod:`servo_axis.run.processes`: the node processes (environment, start,
  stop, CPU pinning, clean-up of Fast DDS shared memory);
* :mod:`servo_axis.run.progress`: the runner's progress watcher and line;
* :mod:`servo_axis.run.runner`: :func:`~servo_axis.run.runner.run_scenario`
  and its errors and result.

Only :mod:`servo_axis.run.progress` imports rclpy, and only when a watcher
is made.
"""
