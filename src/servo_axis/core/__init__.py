"""Numerics of the servo axis: numpy and scipy only, never rclpy.

Every algorithm here is a class or function that can be stepped or called on
arrays without ROS. Time and step are passed in; nothing reads a clock, logs
or publishes.
"""
