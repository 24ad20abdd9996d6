"""The PyBullet "hardware": worlds, robot bodies and sensors (the only package importing pybullet)."""
