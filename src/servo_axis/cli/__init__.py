"""The command line's commands, one module each (``python -m servo_axis COMMAND``).

A command module ``<name>_command.py`` has ``add_parser(commands)``, which
adds its parser (its arguments with their help, their checks as argparse
types from :mod:`~servo_axis.cli.options`) and sets its handler as
``func``, and the handler itself, ``(args) -> exit code``, which imports
what it needs inside it: ``python -m servo_axis list`` or ``--help`` load
no ROS, no numba, no matplotlib. ``servo_axis.__main__`` lists the modules
in the order of the help, builds the parser and dispatches; a new command is
a module here and its name in that list.
"""
