"""``python -m servo_axis.numerics``: see :func:`servo_axis.numerics.main`."""

import sys

from servo_axis.numerics import main

sys.exit(main())
