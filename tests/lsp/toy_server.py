"""`taskflow lsp` with the test suite's toy robot, world and tasks registered (tests/toys.py), as a plugin
package would register its own: the broken-mission corpus is written against them."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import toys

toys.register()

from taskflow.cli import main  # noqa: E402

sys.exit(main(["lsp"]))
