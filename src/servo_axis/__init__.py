"""servo_axis: a ROS 2 (Jazzy) emulation of a machine-tool servo axis and its controllers."""

import os as _os

from servo_axis import numerics as _numerics

# `python -m servo_axis[.module]` starts again in the portable numeric
# environment before numpy loads (servo_axis.numerics); a library import never does.
_numerics.enter()

# The suite's matrices are 3x3 to 8x8: OpenBLAS's threads only contend for
# the cores (a plain-call DLPID loop ran 10x slower with them on a loaded
# 2-core host). A default only: effective if numpy is not yet loaded, and
# inherited by every process started from here (nodes, study workers).
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
