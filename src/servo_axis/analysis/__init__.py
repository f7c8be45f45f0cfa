"""Analysis of recorded runs: signals, error statistics, summaries, text and plots.

Nothing in this package imports rclpy or a ROS message package: a bag is read
as raw CDR payloads (:func:`servo_axis.recording.reader.read_raw`) and
decoded with :mod:`servo_axis.wire.cdr`, so runs can be analysed where ROS is
not installed.

Modules
-------
signals
    :class:`~servo_axis.analysis.signals.Signals` per control step from a bag
    (:func:`~servo_axis.analysis.signals.load_signals`), fault records, and the
    target and controlled output of a run
    (:func:`~servo_axis.analysis.signals.tracking`).
metrics
    Pure arithmetic: tracking-error statistics per run, per reference instant
    and per cycle (:func:`~servo_axis.analysis.metrics.error_statistics`) and
    the contour error of a two-axis circle
    (:func:`~servo_axis.analysis.metrics.contour_error`).
summary
    The typed ``summary.json`` of a run
    (:class:`~servo_axis.analysis.summary.RunSummary`) and of a multi-axis run
    (:class:`~servo_axis.analysis.summary.AxesSummary`): computing, writing
    and reading them back. Each block is computed by the module of its
    subject (``tracking``, ``learning_summary``, ``identification``,
    ``deformation_summary``, ``realtime``, ``contour_summary``), whose names
    ``summary`` re-exports.
serial
    The one serialiser of the summary's dataclasses:
    :func:`~servo_axis.analysis.serial.to_dict` and
    :func:`~servo_axis.analysis.serial.from_dict`, driven by the fields and
    their type hints.
units
    The one unit each quantity is shown in
    (:data:`~servo_axis.analysis.units.QUANTITIES`): a tracking error in um,
    in rad on a rotary table, in every table and figure.
text
    Summaries and per-cycle comparisons as plain-text tables.
plots
    PNG figures of a run, of several runs and of a contour (matplotlib, Agg).
"""
