"""Verification: the compiled mission as a finite model, the checks a model checker answers on it, and a
campaign's records turned into a prediction (``campaign``).

May import: the public plugin API, ``taskflow.mission``, ``taskflow.execution``, ``taskflow.readers``,
``taskflow.catalogue``, ``taskflow.campaigns`` and ``taskflow.testing``; never ``operate`` or ``cli``.
"""
