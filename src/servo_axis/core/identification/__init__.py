"""Identification of a servo axis: the numerics, of two kinds.

* :mod:`~servo_axis.core.identification.online`: paper 003's identifier,
  which runs in the loop during a run (the identifier node) and whose
  estimates the adaptive feedforward applies while the run goes on;
* :mod:`~servo_axis.core.identification.offline`: the identification of a
  whole axis from runs recorded for it (a frequency response, a slow
  reversal), which the ``identify`` command fits into a scenario
  (:mod:`servo_axis.identify`).
"""
