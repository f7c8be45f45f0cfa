"""The suite's own extensions, one module each, registered as entry points in ``pyproject.toml``.

Each module declares one plant model, feedforward term, learning law or
identification method (or a family sharing keys): its parameter schema,
its builder, its cross-key checks, the files it reads and its metadata, as
an entry of :mod:`servo_axis.params.registry`. An outside package does the
same in its own modules and its own ``pyproject.toml``; nothing here is
special to the suite's (``test/data/outside_plugin`` is one).
"""
