"""Online parameter identification (the seam for paper 003's DLPID).

An identifier consumes the state stream at its own period (``T_RLS``) and
publishes estimates that take effect in the feedforward from a step fixed by
configuration (docs/design.md section 4): the PTC's model is replaced from that step on
(:meth:`servo_axis.core.feedforward.ptc.MultiratePtc.replace_model`). An
identifier is a module here (numerics: regression, RLS, PE index) plus its
entry in :mod:`servo_axis.plugins` (an entry point), and its node under
:mod:`servo_axis.nodes`. Built: the numerics of DLPID (``rls``: conditional RLS
with per-parameter forgetting and projection; ``pe``: the PE index;
``dlpid``: the two layers and the signal chain; ``base``: what the node asks
of an identifier). The node is :mod:`servo_axis.nodes.identifier`.
"""
