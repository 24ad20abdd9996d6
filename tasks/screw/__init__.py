"""The screw-fastening paper's tasks (papers/002): the mobile PBVS loop and the arm's homing.

``mobile_pbvs`` holds the paper's control tick and its three registered tasks (``pbvs_platform``,
``pbvs_arm``, ``pbvs_platform_retract``), ``home`` the error handling (``arm_home``), ``prediction``
the part-motion predictor (beyond the paper) and ``data`` what they share across states (mission
data, observation keys, the control period).  The laws shared with other papers (PBVS maths, PID,
impedance) are in :mod:`taskflow_tasks.core`.  Modules here may import numpy, Pinocchio,
``taskflow_robots``, :mod:`taskflow_tasks.core` and the framework's public API; never pybullet.
"""
