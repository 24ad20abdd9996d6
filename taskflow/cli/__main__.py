"""``python -m taskflow.cli``: the ``taskflow`` command."""

import sys

from taskflow.cli import main

sys.exit(main())
