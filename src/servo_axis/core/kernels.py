"""How the compiled kernels are compiled (numba), and where each family of them is.

The plants advance one control period per call, and within it tens to a
hundred integration sub-steps with friction; in plain Python those loops
bound the whole core-only loop (7-15x real time). They, the adaptive PTC's
small matrix work and the GMS feedforward's model are compiled with numba
by :func:`compiled` (``nopython`` mode, ``cache=True``). They are the same
arithmetic as the Python they replaced, operation for operation and in the
same order, with IEEE semantics (no ``fastmath``, no reassociation, no fused
multiply-add), and ``math.sin``/``math.tanh`` go to the same C library as
Python's ``math``: so a plant gives the same numbers bit for bit as the
Python loops it replaced (every shipped scenario's plain-call loop was
compared), and ``test/unit/core/test_kernels.py`` checks each plant compiled
against the same code interpreted (``NUMBA_DISABLE_JIT=1``).

The kernels live beside what uses them, one module per family, each named
``*_kernels.py``:

* :mod:`servo_axis.core.models.ball_screw_kernels`: the Maxwell-slip element
  update and the sub-step loops of both ball screws (rigid, elastic, with
  the ball contact);
* :mod:`servo_axis.core.models.tilting_table_kernels`: the tilting table's
  RK4 sub-steps with Coulomb friction;
* :mod:`servo_axis.core.feedforward.ptc_kernels`: the adaptive PTC's model and
  feedforward segment (003 eq. (11));
* :mod:`servo_axis.core.friction.gms_kernels`: the GMS model's block step (004)
  and its exact element sum;
* :mod:`servo_axis.core.identification.online.dlpid_kernels`: the DLPID's filter bank and
  the conditional RLS step (003).

Compiled code is cached on disk: ``$NUMBA_CACHE_DIR`` if set, else
``__pycache__`` beside each kernel module when that is writable (a source
checkout), else the user's cache directory (``~/.cache/numba``), so an
installed package compiles once per user. A process that finds the cache
imports numba and loads the kernels in about 0.2 s; compiling them takes
about 0.5 s per plant model. numba checks a cached kernel against its own
source file only, not against the files of the kernels it calls, so a kernel
calls only kernels of its own module; and a kernel module imports nothing of
the project but this one (``test/unit/layout/test_import_rules.py``).

A kernel module is imported by the constructors that use it (the plants',
``MaxwellSlip.move``, a compiled ``MultiratePtc``'s, a compiled
``GmsModel``'s, the identifier's) and never at a module's top, so a process
that builds no plant, no adaptive feedforward, no GMS term and no identifier
never imports numba. The kernels work on float64 scalars and contiguous
float64 arrays; the callers own the arrays (element deflections are updated
in place).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba

F = TypeVar("F", bound=Callable[..., Any])


def compiled(fn: F) -> F:
    """``fn`` compiled by numba (nopython, cached on disk, IEEE arithmetic).

    Parameters
    ----------
    fn : callable
        A function of float64 scalars and arrays (numba's ``nopython`` subset).

    Returns
    -------
    callable
        The numba dispatcher: compiled on its first call for each signature,
        or loaded from the on-disk cache.
    """
    return cast(F, numba.njit(cache=True, fastmath=False, nogil=True)(fn))
