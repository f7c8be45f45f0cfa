"""The offline identification of a whole axis, from runs recorded for it (issue 32).

``excitation`` (the periodic test signals: multisine, chirp, PRBS),
``frf`` (the closed-loop frequency response with the excitation as
instrument, its coherence and its uncertainty per line), ``models`` (the
frequency responses of the shipped plant models' linear parts, sampled with
a zero-order hold), ``fit`` (weighted least squares on the models' own keys
with standard errors; the tilting table's time-domain fit),
``friction_fit`` (the friction of a slow reversal by the plants' own laws).
numpy and scipy only; the bag reading, the fit driver and the scenario
writing are in :mod:`servo_axis.identify`.
"""
