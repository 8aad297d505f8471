"""Headless MuJoCo simulator of a Kinect-equipped TurtleBot 2 on a line-following course."""

import os

# MuJoCo picks its OpenGL backend when it is first imported: default to EGL (off-screen, works
# on Mesa without a display) unless the user chose one, so every entry point renders headless.
os.environ.setdefault('MUJOCO_GL', 'egl')
