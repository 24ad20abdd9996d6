"""``taskflow lsp``: the Language Server Protocol server for mission files, over stdio (pygls).

The protocol layer only: it keeps the open buffers in a :class:`~taskflow.lsp.analysis.Workspace`, runs the load
path on a buffer when it opens and :data:`DEBOUNCE_S` after the last change, publishes the diagnostics, and
answers completion, hover, definition, references, document symbols, rename and code actions through the
modules that compute them (:mod:`.completion`, :mod:`.hover`, :mod:`.navigation`, :mod:`.actions`), which work
in 0-based lines and code points (:class:`~taskflow.lsp.document.Span`).  :class:`Context` converts to the
client's position units here, at the boundary.

No request crashes the server: a feature that raises answers "nothing" (and logs the error to stderr).
"""

from __future__ import annotations

import asyncio
import logging
import sys
import threading
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from lsprotocol import types
from pygls.lsp.server import LanguageServer

import taskflow
from taskflow.lsp.analysis import Diagnostic, Workspace
from taskflow.lsp.context import Context
from taskflow.lsp.document import Span

DEBOUNCE_S = 0.05
"""How long after the last change a buffer is analysed again: a burst of keystrokes gives one analysis."""

log = logging.getLogger("taskflow.lsp")
T = TypeVar("T")


class TaskflowServer(LanguageServer):
    def __init__(self) -> None:
        super().__init__("taskflow", taskflow.__version__ if hasattr(taskflow, "__version__") else "0")
        self.buffers = Workspace()
        self.pending: dict[str, asyncio.Task[None]] = {}
        self.by_buffer: dict[str, dict[str, list[Diagnostic]]] = {}  # buffer → file → what its analysis found there
        self.ctx = Context(self.buffers, lambda: self.workspace.position_codec)
        self.warming: threading.Thread | None = None

    def warm_catalogue(self) -> None:
        """Build the catalogue (hover's pages: every registered plugin imported, about 0.6 s) in a thread once a
        document is open, so the first hover does not wait for it."""
        if self.warming is None:
            from taskflow.lsp.knowledge import catalogue

            def build() -> None:
                try:
                    catalogue()
                except Exception:  # the first hover builds it again and reports the error to the client
                    print(f"taskflow lsp: catalogue:\n{traceback.format_exc()}", file=sys.stderr)

            self.warming = threading.Thread(target=build, name="catalogue", daemon=True)
            self.warming.start()

    def analyse_and_publish(self, file: str) -> None:
        """Analyse ``file`` and the open missions that use it (they see its unsaved text), then publish."""
        self.buffers.update(file)
        touched = [file]
        for other in list(self.buffers.texts):
            a = self.buffers.analyses.get(other)
            if other != file and a is not None and str(Path(file).resolve()) in a.used_files:
                self.buffers.update(other)
                touched.append(other)
        self.publish(*touched)

    def publish(self, *buffers: str) -> None:
        """Publish what the analyses of ``buffers`` found, in every file they found something in (and clear the
        files they no longer do).  A file's diagnostics are those of every buffer that shows some there: a
        sub-mission open beside the mission using it shows its own problems and those found through the use.
        Every buffer's diagnostics are taken before any file is published, so no file is sent a problem that
        another of them no longer has (a fixed sub-mission's error, shown in it through the mission)."""
        targets: set[str] = set()
        for file in buffers:
            targets |= set(self.by_buffer.get(file, {}))
            self.by_buffer[file] = self.buffers.diagnostics(file)
            targets |= set(self.by_buffer[file])
        for target in sorted(targets):
            diags = [types.Diagnostic(range=self.ctx.range(target, d.span), message=d.message,
                                      severity=types.DiagnosticSeverity.Error, source="taskflow",
                                      data={"line": d.problem.line, "col": d.problem.col, "hint": d.problem.hint,
                                            "at_use": d.at_use})
                     for shown in self.by_buffer.values() for d in shown.get(target, [])]
            self.text_document_publish_diagnostics(types.PublishDiagnosticsParams(
                uri=self.ctx.uri_of(target), diagnostics=_unique(diags)))

    def schedule(self, file: str) -> None:
        old = self.pending.pop(file, None)
        if old is not None:
            old.cancel()

        async def later() -> None:
            await asyncio.sleep(DEBOUNCE_S)
            self.pending.pop(file, None)
            _guard(lambda: self.analyse_and_publish(file), None)

        self.pending[file] = asyncio.get_running_loop().create_task(later())


def _unique(diags: list[types.Diagnostic]) -> list[types.Diagnostic]:
    out: list[types.Diagnostic] = []
    seen: set[tuple[Any, ...]] = set()
    for d in diags:
        key = (d.range.start.line, d.range.start.character, d.message)
        if key not in seen:
            seen.add(key)
            out.append(d)
    return out


_SERVER: list[TaskflowServer] = []  # the running server, for _guard's report to the client


def _guard(fn: Callable[[], T], default: T) -> T:
    """``fn()``, or ``default`` if it raises: no request crashes the server.  The error goes to stderr and to the
    client's log (``window/logMessage``, type Error), where a test or a user sees it."""
    try:
        return fn()
    except Exception:
        report = f"taskflow lsp: internal error:\n{traceback.format_exc()}"
        print(report, file=sys.stderr)
        for server in _SERVER:
            try:
                server.window_log_message(types.LogMessageParams(type=types.MessageType.Error, message=report))
            except Exception:
                pass
        return default


def build_server() -> TaskflowServer:
    from taskflow.lsp import actions, completion, hover, navigation

    server = TaskflowServer()
    _SERVER[:] = [server]
    ctx = server.ctx

    @server.feature(types.TEXT_DOCUMENT_DID_OPEN)
    def did_open(ls: TaskflowServer, params: types.DidOpenTextDocumentParams) -> None:
        file = ctx.file_of(params.text_document.uri)
        ls.buffers.texts[file] = params.text_document.text
        _guard(lambda: ls.analyse_and_publish(file), None)
        ls.warm_catalogue()

    @server.feature(types.TEXT_DOCUMENT_DID_CHANGE)
    def did_change(ls: TaskflowServer, params: types.DidChangeTextDocumentParams) -> None:
        file = ctx.file_of(params.text_document.uri)
        ls.buffers.texts[file] = ls.workspace.get_text_document(params.text_document.uri).source
        ls.schedule(file)

    @server.feature(types.TEXT_DOCUMENT_DID_SAVE)
    def did_save(ls: TaskflowServer, params: types.DidSaveTextDocumentParams) -> None:
        file = ctx.file_of(params.text_document.uri)
        if file in ls.buffers.texts:
            ls.schedule(file)

    @server.feature(types.TEXT_DOCUMENT_DID_CLOSE)
    def did_close(ls: TaskflowServer, params: types.DidCloseTextDocumentParams) -> None:
        file = ctx.file_of(params.text_document.uri)
        ls.buffers.close(file)
        _guard(lambda: ls.publish(file), None)  # takes back what it showed in other files
        ls.by_buffer.pop(file, None)

    def _sync(uri: str) -> str:
        """The buffer's file, analysed now if a change is still waiting for its debounce (a request sees the
        text as typed)."""
        file = ctx.file_of(uri)
        pending = server.pending.pop(file, None)
        if pending is not None:
            pending.cancel()
            server.analyse_and_publish(file)
        return file

    def _at(params: Any, answer: Callable[[str, int, int], T]) -> T | None:
        """``answer(file, line, code point)`` for a request at ``params.position`` (guarded: None if it raises)."""
        def run() -> T | None:
            file = _sync(params.text_document.uri)
            line, col = ctx.position(file, params.position)
            return answer(file, line, col)
        return _guard(run, None)

    @server.feature(types.TEXT_DOCUMENT_COMPLETION,
                    types.CompletionOptions(trigger_characters=[":", " ", "$", ".", "{", ",", "/"]))
    def on_completion(ls: TaskflowServer, params: types.CompletionParams) -> types.CompletionList | None:
        return _at(params, lambda file, line, col: completion.complete(ctx, file, line, col))

    @server.feature(types.TEXT_DOCUMENT_HOVER)
    def on_hover(ls: TaskflowServer, params: types.HoverParams) -> types.Hover | None:
        return _at(params, lambda file, line, col: hover.hover(ctx, file, line, col))

    @server.feature(types.TEXT_DOCUMENT_DEFINITION)
    def on_definition(ls: TaskflowServer, params: types.DefinitionParams) -> list[types.Location] | None:
        return _at(params, lambda file, line, col: navigation.definition(ctx, file, line, col))

    @server.feature(types.TEXT_DOCUMENT_REFERENCES)
    def on_references(ls: TaskflowServer, params: types.ReferenceParams) -> list[types.Location] | None:
        return _at(params, lambda file, line, col: navigation.references(ctx, file, line, col,
                                                                       params.context.include_declaration))

    @server.feature(types.TEXT_DOCUMENT_DOCUMENT_SYMBOL)
    def on_symbols(ls: TaskflowServer, params: types.DocumentSymbolParams) -> list[types.DocumentSymbol] | None:
        return _guard(lambda: navigation.symbols(ctx, _sync(params.text_document.uri)), None)

    @server.feature(types.TEXT_DOCUMENT_PREPARE_RENAME)
    def on_prepare_rename(ls: TaskflowServer, params: types.PrepareRenameParams) -> types.Range | None:
        return _at(params, lambda file, line, col: navigation.prepare_rename(ctx, file, line, col))

    @server.feature(types.TEXT_DOCUMENT_RENAME)
    def on_rename(ls: TaskflowServer, params: types.RenameParams) -> types.WorkspaceEdit | None:
        return _at(params, lambda file, line, col: navigation.rename(ctx, file, line, col, params.new_name))

    @server.feature(types.TEXT_DOCUMENT_CODE_ACTION,
                    types.CodeActionOptions(code_action_kinds=[types.CodeActionKind.QuickFix]))
    def on_code_action(ls: TaskflowServer, params: types.CodeActionParams) -> list[types.CodeAction] | None:
        def run() -> list[types.CodeAction] | None:
            file = _sync(params.text_document.uri)
            start = ctx.position(file, params.range.start)
            end = ctx.position(file, params.range.end)
            return actions.code_actions(ctx, file, Span(start[0], start[1], end[0], end[1]))
        return _guard(run, None)

    return server


def main() -> int:
    """Serve on stdin/stdout until the client says exit."""
    logging.basicConfig(stream=sys.stderr, level=logging.WARNING)
    build_server().start_io()
    return 0
