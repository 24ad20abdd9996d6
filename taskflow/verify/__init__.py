"""Verification: the compiled mission as a finite model (``model``), the checks a model checker answers on it
(``checks``, with Storm through ``stormpy``; ``export``: the model as PRISM or JANI text), counterexamples a
person can read and the engine can replay (``counterexample``), and a campaign's records turned into a
prediction (``campaign``).

May import: the public plugin API, ``taskflow.mission``, ``taskflow.execution``, ``taskflow.readers``,
``taskflow.catalogue`` and ``taskflow.campaigns``; never ``operate`` or ``cli``
(``tests/test_dependency_direction.py`` enforces it).
"""

from taskflow.verify.checks import CheckResult, Verification, verify_mission

__all__ = ["CheckResult", "Verification", "verify_mission"]
