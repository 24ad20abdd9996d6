"""The screw-fastening paper's tasks (papers/002): the mobile PBVS loop and the arm's homing.

Control laws shared with other papers (PBVS maths, PID, impedance) live in the shared laws of
``taskflow_tasks``; this package binds them to the paper's states.  Modules here may import numpy,
Pinocchio, ``taskflow_robots``, the shared laws and the framework's public API; never pybullet.
"""
