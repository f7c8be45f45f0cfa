"""Realtime mode in one place: what a node and the runner do when the plant's clock is the wall's.

Nothing here imports rclpy (the nodes wire these parts to their topics and
timers), and nothing of the project but :mod:`servo_axis.core`:

* :mod:`.deadlines`: the arithmetic of a realtime clock (deadlines, the
  ticks due, misses, lateness, whether an answer can still be used);
* :mod:`.scheduling`: which threads of a node get a realtime priority, and
  when;
* :mod:`.clock`: the plant's clock thread and its record, and the loop
  around an outside plant as its feedback measures it;
* :mod:`.late`: what a node does with what is late: the current a drive
  holds, the states a node that fell behind still answers;
* :mod:`.supervisor`: the runner's last resort, a realtime run that lasts
  far longer than its simulated time.

Where the rest is: the summary's ``realtime`` block
(:mod:`servo_axis.analysis.realtime_summary`), the host's realtime floor
(:mod:`servo_axis.run.floor`), which jumps of a per-sample stream a node
takes (:class:`servo_axis.wire.streams.StreamGate`) and how long a node
waits for a peer (:mod:`servo_axis.nodes.lockstep`); see
docs/explanation/realtime.md.
"""
