"""Recording: rosbag2-layout MCAP bags."""
