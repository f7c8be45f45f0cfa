"""The offline identification of an axis: its three commands, from recorded runs.

* ``python -m servo_axis friction-table RUN_DIR``: :mod:`.friction`, the
  friction a slow reversal measures and the data-based friction table of it;
* ``python -m servo_axis gms-fit RUN_DIR``: :mod:`.gms_fit`, the GMS model
  (paper 004) fitted to a slow reversal;
* ``python -m servo_axis identify RUN_DIR... --model NAME --out SCENARIO.yaml``,
  a plant model's keys and its friction fitted into a scenario that runs it:
  :mod:`.data` reads the runs (or the plain-call loops' trajectories),
  :mod:`.driver` estimates the frequency responses, fits the plant model's
  own keys and the friction and validates on a held-out run, :mod:`.writer`
  writes the scenario, :mod:`.report` the figures and the table, :mod:`.study`
  the ``sysid`` block of a sweep point.

The commands are in :mod:`servo_axis.cli`; the numerics in
:mod:`servo_axis.core.identification.offline` (and the GMS fit in
:mod:`servo_axis.core.friction.gms_fitting`). Not here: the online identifier
of paper 003 (:mod:`servo_axis.core.identification.online`), which runs
during a run. No rclpy; see docs/how-to/identify-your-axis.md and
docs/how-to/friction-models.md.
"""

#: The plant models ``identify`` fits (imported by the command line without numpy).
MODELS = ("ball_screw", "elastic_ball_screw", "tilting_table")
