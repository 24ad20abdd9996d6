"""What is registered, described: the catalogue of tasks, robots, worlds and sensor streams as data
(``catalogue``) and as text or markdown (``catalogue_render``), the mission JSON Schema completed for editors
(``completions``), a mission's machine as a diagram (``graph``) and the conformance check over every
registered plugin (``conformance``).

May import: the public plugin API and ``taskflow.mission``; never ``execution``, ``readers``, ``operate``,
``campaigns`` or ``cli`` (``tests/test_dependency_direction.py`` enforces it).
"""
