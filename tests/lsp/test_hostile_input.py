"""No request crashes the server: the hostile-input corpus replayed through it.

The corpus: every file of the broken-mission corpus (alias bombs, control characters, tabs, python tags, unclosed
brackets, ...), every shipped mission cut at many points (what an editor sends while a file is typed), and
texts built to hurt (deep nesting, a huge file, binary noise, a lone surrogate's replacement, CRLF).  After each
text the server must publish diagnostics for it, and answer completion, hover, definition, references,
symbols, prepare-rename, rename and code actions at several positions with a result or nothing — never an
error — and afterwards still diagnose a good file as before.
"""

from __future__ import annotations

import random

import pytest
from lsp_session import BROKEN, MISSIONS, change_doc, open_doc
from lsprotocol import types

pytestmark = [pytest.mark.machine, pytest.mark.asyncio]


def _cuts(text: str, n: int, rng: random.Random) -> list[str]:
    points = sorted(rng.sample(range(1, len(text)), n))
    return [text[:p] for p in points]


def _corpus() -> list[str]:
    rng = random.Random(23)
    texts = [p.read_text(encoding="utf-8", errors="replace") for p in sorted(BROKEN.glob("*.yaml"))]
    for name in ("screw_fastening.yaml", "viki_hyco.yaml", "visual_path_oval.yaml", "lib/screw_operation.yaml"):
        texts += _cuts((MISSIONS / name).read_text(), 12, rng)
    shipped = (MISSIONS / "viki_hyco.yaml").read_text()
    lines = shipped.splitlines()
    texts += [
        "", "\n\n\n", "---\n---\n", "[" * 5000, "{a: " * 3000, "- " * 4000 + "x",
        "mission: x\nmachine:\n  states:\n" + "".join(f"    s{i}: {{final: true}}\n" for i in range(25_000)),
        "".join(chr(rng.randrange(1, 0xD7FF)) for _ in range(3000)),
        shipped.replace("\n", "\r\n"),
        shipped.replace("to: ", "to: \ufffd", 3),
        "\n".join(rng.sample(lines, len(lines))),  # the shipped lines shuffled
        "\n".join(line[: rng.randrange(len(line) + 1)] for line in lines),  # every line cut short
        shipped + "\n  \t odd: [\n",
        "machine: &a [*a]\n",
        "mission: !!python/object:os.system x\n",
    ]
    return texts


async def _ask_everything(client, uri: str, text: str, rng: random.Random) -> None:
    lines = text.split("\n") or [""]
    doc = types.TextDocumentIdentifier(uri=uri)
    spots = [(0, 0), (len(lines), 0)] + [(ln, rng.randrange(len(lines[ln]) + 2))
                                          for ln in (rng.randrange(len(lines)) for _ in range(3))]
    for line, col in spots:
        p = types.Position(line=line, character=col)
        await client.text_document_completion_async(types.CompletionParams(text_document=doc, position=p))
        await client.text_document_hover_async(types.HoverParams(text_document=doc, position=p))
        await client.text_document_definition_async(types.DefinitionParams(text_document=doc, position=p))
        await client.text_document_references_async(types.ReferenceParams(
            text_document=doc, position=p, context=types.ReferenceContext(include_declaration=True)))
        await client.text_document_prepare_rename_async(types.PrepareRenameParams(text_document=doc, position=p))
        await client.text_document_rename_async(types.RenameParams(text_document=doc, position=p, new_name="renamed"))
        await client.text_document_code_action_async(types.CodeActionParams(
            text_document=doc, range=types.Range(start=p, end=p),
            context=types.CodeActionContext(diagnostics=[])))
    await client.text_document_document_symbol_async(types.DocumentSymbolParams(text_document=doc))


async def test_the_hostile_corpus_through_every_request_never_crashes_the_server(toy_client):
    rng = random.Random(7)
    path = MISSIONS / "viki_hyco.yaml"
    good = path.read_text()
    uri = path.resolve().as_uri()
    assert await open_doc(toy_client, path) == []
    corpus = _corpus()
    assert len(corpus) > 150
    for version, text in enumerate(corpus, start=2):
        diags = await change_doc(toy_client, path, text, version)  # a pygls error here would fail the request
        assert all(d.range.start.line >= 0 and d.message for d in diags)
        await _ask_everything(toy_client, uri, text, rng)
    assert toy_client.error is None
    errors = [m.message for m in toy_client.log_messages if m.type == types.MessageType.Error]
    assert not errors, errors[0]  # a feature that raised (the server answered "nothing" and logged it)
    assert await change_doc(toy_client, path, good, len(corpus) + 2) == []
    bad = good.replace("task: {name: viki_hyco", "task: {name: viki_hyko", 1)
    (d,) = await change_doc(toy_client, path, bad, len(corpus) + 3)
    assert "unknown task 'viki_hyko'" in d.message
