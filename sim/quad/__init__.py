"""The quadcopter's world, ``quad_room``, of the visual-path-following paper (Toro-Arcila et al., papers/003).

A textured room with green columns, flown by the quadcopter with its forward camera.  The modules:
``params`` (the world's parameters and their fidelity), ``scene`` (the PyBullet room, textures and
rendering), ``landmarks`` (the geometric camera's landmarks and projection), ``response`` (the drone's
command response models), ``sensors`` (the camera: frames, latency, blackouts), ``scoring`` (collisions,
path deviation, the ground-truth ε and the summary), ``teaching`` (teach-by-showing: keyframe images on
disk) and ``world`` (the registered ``QuadRoom``).

May import: numpy, OpenCV, pybullet, ``taskflow_robots.quadcopter``, the shared simulator core
(``taskflow_sim`` stepping, faults, command delay) and the framework's public modules only.
"""
