"""A learning law's entry point that names an object which is not a ``LearningLawEntry``."""

LAW = {"period": "cycle", "side": "target"}
