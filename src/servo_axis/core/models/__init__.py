"""Plant models: the Plant protocol (:mod:`.base`) and one module per model.

``ball_screw``: the ball-screw axis of paper 000 eq. (30) (rigid body,
resonance modes, dead time, rolling friction). A model is chosen by the
parameter ``plant.model`` among the installed entry points
(:mod:`servo_axis.params.registry`).
"""
