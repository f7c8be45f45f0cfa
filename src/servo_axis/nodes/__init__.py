"""Thin rclpy nodes: parameters -> core object -> publishers -> subscriptions -> timers."""
