"""Follow a yellow line on the floor with a camera: detection, control and the ROS node."""
