"""The log times of a recording on the simulation timeline.

The recorder logs every message at its simulation time, as ``ros2 bag record
--use-sim-time`` does, so that a viewer's timeline shows the simulated
seconds and ``metadata.yaml``'s ``starting_time`` and ``duration`` are those
of the simulation. :class:`SimTimeline` decides the log time of each message
from the stamps alone, never from the wall clock:

* a stamped message (``sensor_msgs/JointState``: ``header.stamp``;
  ``rosgraph_msgs/Clock``: ``clock``) is logged at its stamp;
* an unstamped one (``std_msgs/Float64MultiArray``) at :attr:`SimTimeline.now_ns`,
  the simulation time the recorder has seen so far (0 before any).

What moves ``now_ns``: only the stamps of the *clock topics*, the streams
whose stamp is the simulation's present: ``/clock`` and the per-sample
streams of the loop (the recorder's ``counted_topics``, ``state`` and
``command``). The other stamped streams are stamped ahead of the present on
purpose (``reference`` up to ``preview_steps`` samples, ``learning/correction``
up to a learning cycle), so they are logged at their stamps but do not drag
the log times of the unstamped messages ahead of the plant.

Junk stamps (a stranger on the topic publishing 1e9 s, a negative time)
must not stretch the timeline:

* a clock-topic stamp moves ``now_ns`` only if it lies in
  ``(now_ns, now_ns + max_step_ns]`` (1 s by default; the plant's stamps
  advance by one control period);
* any stamp is the message's log time only if it lies in
  ``[0, now_ns + max_lead_ns]`` (2.5 s by default: the learning unit's
  corrections are for the next cycle, at most 1.99 s ahead, and may come
  while the recorder is up to ``max_recorder_lag_steps`` behind); a stamp
  outside that window, and a payload whose stamp cannot be read, is logged
  at ``now_ns`` instead.

The recorder must therefore see the start of the simulation: started by hand
more than ``max_step_ns`` into a run, it logs everything at 0.
"""

from __future__ import annotations

__all__ = ["MAX_LEAD_NS", "MAX_STEP_NS", "SimTimeline"]

#: Largest step of the simulation time one clock-topic stamp may make (ns).
MAX_STEP_NS = 1_000_000_000

#: Largest lead of a logged stamp over the simulation time seen so far (ns).
MAX_LEAD_NS = 2_500_000_000


class SimTimeline:
    """Simulation time seen so far, and the log time of each message.

    Parameters
    ----------
    max_step_ns : int
        A clock-topic stamp moves :attr:`now_ns` only if it is at most this
        far ahead of it.
    max_lead_ns : int
        A stamp is a message's log time only if it is at most this far ahead
        of :attr:`now_ns` (and not negative).
    """

    __slots__ = ("max_lead_ns", "max_step_ns", "now_ns")

    def __init__(self, *, max_step_ns: int = MAX_STEP_NS, max_lead_ns: int = MAX_LEAD_NS) -> None:
        if max_step_ns < 0 or max_lead_ns < 0:
            raise ValueError(f"expected bounds >= 0, got {max_step_ns}, {max_lead_ns}")
        self.max_step_ns = max_step_ns
        self.max_lead_ns = max_lead_ns
        #: The simulation time seen so far (ns): 0 before any clock-topic stamp.
        self.now_ns = 0

    def log_time(self, stamp_ns: int | None, *, clock: bool = False) -> int:
        """The log time (ns) of a message with this stamp; advance the timeline.

        Parameters
        ----------
        stamp_ns : int or None
            The message's stamp (ns), None for an unstamped message or a
            stamp that could not be read.
        clock : bool
            Whether the message is of a clock topic (its stamp is the
            present of the simulation).

        Returns
        -------
        int
            ``stamp_ns`` if it lies in ``[0, now_ns + max_lead_ns]``, else
            :attr:`now_ns` (after a clock-topic stamp moved it).
        """
        now = self.now_ns
        if stamp_ns is None:
            return now
        if clock and now < stamp_ns <= now + self.max_step_ns:
            self.now_ns = stamp_ns
            return stamp_ns
        if 0 <= stamp_ns <= now + self.max_lead_ns:
            return stamp_ns
        return now
