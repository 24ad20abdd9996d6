"""The ViKi-HyCo paper's control laws and tasks (papers/000): hybrid visual/kinematic positioning of a car.

What it holds: the image features and interaction matrix (:mod:`.image_features`, eq. 7-9), the desired box
(:mod:`.bbox_target`, eq. 19), the car visual servo (:mod:`.car_visual_servo`, eq. 10, 20-24), the one-tick
law and its geometry (:mod:`.laws`), the evidence rules (:mod:`.evidence`) and the registered tasks
``viki_hyco`` (:mod:`.hyco`) and ``viki_rotate`` (:mod:`.rotation`).
What it may import: numpy, the framework's public plugin API (``taskflow.api``, ``specs``, ``messages``,
``spatial``, ...), ``taskflow_robots`` and the laws shared by several papers (``taskflow_tasks`` outside the
paper packages); never another paper's package and never PyBullet or ``taskflow_sim``.
"""
