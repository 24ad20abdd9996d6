"""The language server under test (tests/lsp), driven as a real LSP client over stdio (pytest-lsp): ``client``
starts ``taskflow lsp`` (the real command, shipped missions), ``toy_client`` the same server with the test suite's
toy plugins registered (the broken-mission corpus); tests/conftest.py makes both fixtures.  Helpers open a
document and wait for its diagnostics.  Not a conftest.py of tests/lsp: a second module named ``conftest`` would
stand in for tests/conftest.py where other tests import from it."""

from __future__ import annotations

import asyncio
import sys
from pathlib import Path

import pytest_lsp
from lsprotocol import types
from pytest_lsp import ClientServerConfig, LanguageClient

HERE = Path(__file__).resolve().parent / "lsp"
ROOT = HERE.parents[1]
MISSIONS = ROOT / "missions"
BROKEN = ROOT / "tests" / "broken"


async def _session(client: LanguageClient):
    await client.initialize_session(types.InitializeParams(
        capabilities=pytest_lsp.client_capabilities("visual-studio-code"), root_uri=MISSIONS.as_uri()))
    yield
    await client.shutdown_session()


@pytest_lsp.fixture(config=ClientServerConfig(server_command=[sys.executable, "-m", "taskflow.cli", "lsp"]))
async def client(lsp_client: LanguageClient):
    async for step in _session(lsp_client):
        yield step


@pytest_lsp.fixture(config=ClientServerConfig(server_command=[sys.executable, str(HERE / "toy_server.py")]))
async def toy_client(lsp_client: LanguageClient):
    async for step in _session(lsp_client):
        yield step


async def open_doc(client: LanguageClient, path: Path, text: str | None = None, version: int = 1,
                   timeout: float = 20.0) -> list[types.Diagnostic]:
    """Open ``path`` (with ``text`` instead of its contents) and return the diagnostics published for it."""
    uri = path.resolve().as_uri()
    client.diagnostics.pop(uri, None)
    client.text_document_did_open(types.DidOpenTextDocumentParams(text_document=types.TextDocumentItem(
        uri=uri, language_id="yaml", version=version, text=path.read_text() if text is None else text)))
    return await wait_diagnostics(client, uri, timeout)


async def change_doc(client: LanguageClient, path: Path, text: str, version: int,
                     timeout: float = 20.0) -> list[types.Diagnostic]:
    """Replace the whole text of the open ``path`` and return the diagnostics published after the change."""
    uri = path.resolve().as_uri()
    client.diagnostics.pop(uri, None)
    client.text_document_did_change(types.DidChangeTextDocumentParams(
        text_document=types.VersionedTextDocumentIdentifier(uri=uri, version=version),
        content_changes=[types.TextDocumentContentChangeWholeDocument(text=text)]))
    return await wait_diagnostics(client, uri, timeout)


async def wait_diagnostics(client: LanguageClient, uri: str, timeout: float = 20.0) -> list[types.Diagnostic]:
    deadline = asyncio.get_running_loop().time() + timeout
    while uri not in client.diagnostics:
        assert asyncio.get_running_loop().time() < deadline, f"no diagnostics for {uri}"
        await asyncio.sleep(0.005)
    return list(client.diagnostics[uri])


def pos(text: str, needle: str, offset: int = 0, nth: int = 0) -> types.Position:
    """The position just after the ``nth`` occurrence of ``needle`` in ``text`` (plus ``offset`` characters)."""
    at = -1
    for _ in range(nth + 1):
        at = text.index(needle, at + 1)
    at += len(needle) + offset
    line = text.count("\n", 0, at)
    return types.Position(line=line, character=at - (text.rfind("\n", 0, at) + 1))
