"""The ViKi-HyCo paper's world (papers/000): ``viki_ground``, a racecar or husky, a floor and one waste-like object.

What it holds: the world (:mod:`.world`: the registered ``viki_ground``) split into its parameters
(:mod:`.params`), its scene (:mod:`.scene`: object placement, camera models, ground truth of the object seen
from the robot), its sensors (:mod:`.sensors`: the two cameras as declared sensor streams) and its scoring
(:mod:`.scoring`); the objects and their analytic ray casts (:mod:`.objects`), the ground-truth body
clearance (:mod:`.clearance`), the camera model and the detector's dropout (:mod:`.camera`), the two
perception modes (:mod:`.perception_geometric`, :mod:`.perception_rendered`) and the paper's LiDAR /
depth-camera fusion (:mod:`.depth`, eq. 11-18).
What it may import: numpy, pybullet, the framework's public plugin API (``taskflow.api``, ``messages``,
``spatial``, ``fidelity``, ``registry``, ...), ``taskflow_robots`` and the simulator's shared core
(``taskflow_sim`` outside the paper packages); never another paper's package, never ``taskflow_tasks``.
"""
