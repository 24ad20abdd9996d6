"""What a language-server feature reads (:class:`Context`): the workspace of buffers, and the conversions between
files and URIs and between code-point spans and the client's position units.  Its own module so that the
features (completion, hover, navigation, actions) and the server that calls them import it, not each other."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from lsprotocol import types
from pygls.uris import from_fs_path, to_fs_path
from pygls.workspace.position_codec import PositionCodec, ServerTextPosition, ServerTextRange

from taskflow.lsp.analysis import Workspace
from taskflow.lsp.document import Span


class Context:
    """The buffers (``ws``) and the client's position codec (``codec()``: negotiated at initialisation)."""

    def __init__(self, ws: Workspace, codec: Callable[[], PositionCodec]) -> None:
        self.ws = ws
        self.codec = codec

    @staticmethod
    def file_of(uri: str) -> str:
        return to_fs_path(uri) or uri

    @staticmethod
    def uri_of(file: str) -> str:
        return from_fs_path(str(Path(file).resolve())) or file

    def _lines(self, file: str) -> list[str]:
        """The buffer's lines with their ends, and the empty last line after a final newline (where the cursor is
        when typing at the end of a file: ``splitlines`` drops it, and the codec would clamp the position onto
        the line above)."""
        text = self.ws.text_of(file) or ""
        lines = text.splitlines(True)
        if not lines or lines[-1].endswith(("\n", "\r")):
            lines.append("")
        return lines

    def range(self, file: str, span: Span) -> types.Range:
        return self.codec().range_to_client_units(self._lines(file), ServerTextRange(
            ServerTextPosition(span.line, span.col), ServerTextPosition(span.end_line, span.end_col)))

    def location(self, file: str, span: Span) -> types.Location:
        return types.Location(uri=self.uri_of(file), range=self.range(file, span))

    def position(self, file: str, pos: types.Position) -> tuple[int, int]:
        """A client position as (line, code point)."""
        p = self.codec().position_from_client_units(self._lines(file), pos)
        return p.line, p.character
