"""A finished run's record read back: the run with its mission (``recorded``), the terminal report
(``report``), figures (``plots``), the MCAP telemetry export (``telemetry``) and the scene a mission draws
(``scene``).

May import: the public plugin API, ``taskflow.mission`` and ``taskflow.execution`` (the record formats it
reads are defined there); never ``operate``, ``campaigns``, ``catalogue`` or ``cli``
(``tests/test_dependency_direction.py`` enforces it).
"""
