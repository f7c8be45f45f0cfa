"""Recording: rosbag2-layout MCAP bags (writer, reader, message definitions).

Modules
-------
definitions
    ``ros2msg`` definition text, RIHS01 type hash and class of a message type.
writer
    :class:`BagWriter`, which writes a bag from CDR payloads.
reader
    :func:`read_raw` and :func:`read_metadata`; never imports ROS.
deserialize
    :func:`read_messages`, which deserialises with rclpy (imported when called).
timeline
    :class:`SimTimeline`: the log time (simulation time) of each recorded message.
recover
    :func:`recover_bag`: a bag whose recorder died made readable again.
errors
    :class:`BagError` (:class:`NoBagError`, :class:`NotMcapError`) and
    :class:`BagWriteError`.

The package imports none of them: code that must not load ROS (the
analysis, ``reader``) imports its module directly, and only ``deserialize``
and ``definitions`` reach rclpy or the ament index (when called).
"""
