"""Control laws of the quadcopter's visual path following (Toro-Arcila et al., papers/003).

The pure laws: ``homography`` (the homography-based visual servoing, eqs. 2–7, 31–32), ``hierarchy``
(collision and visibility tasks and their hierarchy, eqs. 8–20), ``obstacle_memory`` (an obstacle
remembered in the body frame); the perception of rendered frames (``perception``); and the registered
tasks ``visual_path_servo`` and ``visual_path_rematch`` (``visual_path``).

May import: numpy, OpenCV, ``taskflow_robots.quadcopter`` (the camera's parameters) and the framework's
public modules; never pybullet or ``taskflow_sim``.
"""
