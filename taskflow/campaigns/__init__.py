"""Campaigns: many seeded runs of a mission (``batch``) on a backend (``backends``: in process, a local pool
or Ray; ``ray_cluster``: a multi-node Ray cluster on one machine, for the tests), the campaign directory
(``campaign``), its statistics (``stats``), the comparison of two campaigns (``compare``) and a campaign's
figures (``campaign_plots``).

May import: the public plugin API, ``taskflow.mission``, ``taskflow.execution``, ``taskflow.readers`` and
``taskflow.catalogue``; never ``operate`` or ``cli`` (``tests/test_dependency_direction.py`` enforces it).
"""
