"""Operating and watching a run: the HTTP control endpoint and its client (``control_http``), the web view's
JSON (``view``) and routes (``view_http``), a finished run served for replay (``replay``) and the page itself
(``web/``).

May import: the public plugin API, ``taskflow.mission``, ``taskflow.execution``, ``taskflow.readers`` and
``taskflow.campaigns`` (the campaign page, ``campaign_view``, reads a batch folder with the reader that
``taskflow compare`` uses: ``campaigns.compare.load_batch``); never ``catalogue``, ``verify``, ``lsp`` or ``cli``.  Inside it the import order is one way:
``replay`` → ``control_http`` → ``view_http`` → ``view`` (``tests/test_dependency_direction.py`` enforces
the package rule and that no two framework modules import each other, at any depth).
"""
