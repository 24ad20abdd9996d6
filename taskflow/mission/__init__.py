"""The mission format and its compiler: a YAML file in, a :class:`~taskflow.mission.model.CompiledMission` out.

Holds the YAML reader that remembers positions (``yamlsrc``), the file format as pydantic models
(``schema``), sub-missions (``submission``), pydantic errors mapped to file positions (``diagnostics``), the
guard language (``guards``), random world parameters (``distributions``), the declared mission data and its
checked run-time view (``data``), the task/robot/world contract checks (``contracts``), the compiler's passes
(``compile/``), the compiled model (``model``) and the loader that strings them together (``loader``).

May import: the public plugin API only (``taskflow.api``, ``specs``, ``registry``, ``units``, ``errors``, ...);
nothing of ``execution``, ``readers``, ``operate``, ``campaigns``, ``catalogue`` or ``cli`` (it is the
bottom layer of the machinery; ``tests/test_dependency_direction.py`` enforces it).
"""
