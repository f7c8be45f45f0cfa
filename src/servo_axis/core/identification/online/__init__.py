"""The online identifier of paper 003: estimates during a run, sample by sample.

An identifier consumes the state stream at its own period (``T_RLS``) and
publishes estimates that take effect in the feedforward from a step fixed by
configuration (docs/design.md section 4): the PTC's model is replaced from
that step on (:meth:`servo_axis.core.feedforward.ptc.MultiratePtc.replace_model`).
The numerics of the DLPID: ``rls`` (conditional RLS with per-parameter
forgetting and projection), ``pe`` (the PE index), ``dlpid`` (the two layers
and the signal chain), ``dlpid_kernels`` (its filter bank and conditional RLS
step, compiled with numba), ``base`` (what the identifier node asks of a
method: :class:`~servo_axis.core.identification.online.base.OnlineIdentifier`).
A method is a module here plus its entry (an entry point; the suite's is
:mod:`servo_axis.plugins.dlpid`); the node that runs it is
:mod:`servo_axis.nodes.identifier`, the summary's block of its estimates
:mod:`servo_axis.analysis.identification_summary`.
"""
