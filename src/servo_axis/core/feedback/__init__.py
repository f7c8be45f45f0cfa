"""The per-sample feedback: discrete filters, PID, disturbance observer, the loop with its
trips, and :func:`.output.controlled_output`, the one place that picks the controlled output."""
