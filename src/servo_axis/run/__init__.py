"""Running a scenario: from the scenario file to a recorded, summarised run.

:func:`servo_axis.run.runner.run_scenario` goes through the parts in order;
each reads the run's plan (:class:`servo_axis.params.run_plan.RunPlan`: the
scenario resolved once, per axis its roles, values, topics, handshakes and
files), none asks the scenario itself.

* :mod:`~servo_axis.run.options`: :class:`~servo_axis.run.options.RunOptions`;
* :mod:`~servo_axis.run.prepare`: the options checked, the plan made, the run
  directory written, the header printed;
* :mod:`~servo_axis.run.start`: the runner's progress watchers, the nodes, a
  dead node's restart;
* :mod:`~servo_axis.run.watch`: the watch loop and its checks (stall, outside
  nodes), :mod:`~servo_axis.run.deaths`: the node-death policy;
* :mod:`~servo_axis.run.stop`: every process stopped, a dead recorder's bag
  recovered;
* :mod:`~servo_axis.run.summarise`: ``summary.json`` with the run's health,
  the plots;
* :mod:`~servo_axis.run.state`: what the run holds while it runs;
* :mod:`~servo_axis.run.processes`: the node processes (environment, start,
  stop, CPU pinning), :mod:`~servo_axis.run.fastdds`: the clean-up of Fast
  DDS shared memory and participant ids;
* :mod:`~servo_axis.run.progress`: the runner's progress watcher and line;
* :mod:`~servo_axis.run.live` (the live view's process),
  :mod:`~servo_axis.run.live_view` (its runner side),
  :mod:`~servo_axis.run.live_channels` (its pieces without ROS).

Only :mod:`servo_axis.run.progress` imports rclpy, and only when a watcher
is made (and :mod:`servo_axis.run.live` in its own process).
"""
