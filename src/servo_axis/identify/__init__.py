"""Identify an axis from recorded runs and write a scenario that runs it.

``python -m servo_axis identify RUN_DIR... --model NAME --out SCENARIO.yaml``:
:mod:`.data` reads the runs (or the plain-call loops' trajectories),
:mod:`.driver` estimates the frequency responses, fits the plant model's
own keys and the friction and validates on a held-out run, :mod:`.writer`
writes the scenario, :mod:`.report` the figures and the table;
:mod:`servo_axis.cli.identify_command` is the command. The numerics are in
:mod:`servo_axis.core.identification.offline`. No rclpy; see
docs/how-to/identify-your-axis.md.
"""

#: The plant models ``identify`` fits (imported by the command line without numpy).
MODELS = ("ball_screw", "elastic_ball_screw", "tilting_table")
