"""A compiled mission run: the engine state on ``transitions`` (``engine``), the tick by tick executor
(``executor``), the control loop with its clock and signals (``runtime``) and what it returns (``summary``),
the operator's channel into a run (``control``: actions applied at tick boundaries, and the endpoint protocol
the run serves them from), the scripted backend (``scripted``: a machine driven by a script, no simulator),
what a run writes (``records``, camera ``frames``, ``provenance``) and the bounded,
untrusted reading of those files (``record_io``, shared by every reader).

May import: the public plugin API and ``taskflow.mission``; never ``readers``, ``operate``, ``campaigns``,
``catalogue`` or ``cli`` (the HTTP endpoint is handed in by the caller as a
:class:`~taskflow.execution.control.ControlEndpoint`; ``tests/test_dependency_direction.py`` enforces it).
"""
