"""The test suite's process in the portable numeric environment (``-p`` in pyproject.toml).

The suite compares the plain-call loops it runs in its own process with the
bags of node processes, which compute in the pin
(:func:`servo_axis.run.processes.ros_environment`): so must it. Loaded with
``-p`` from the project's pytest options, it is imported before pytest
captures any output, and :func:`~servo_axis.numerics.restart` starts pytest
again with the same arguments in the pin (pytest-xdist's workers inherit it).
"""

from servo_axis.numerics import restart

restart()
