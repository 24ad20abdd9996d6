"""``taskflow lsp``: mission authoring in any editor through the Language Server Protocol (docs/editors.md).

:mod:`.document` (where things are in the text), :mod:`.analysis` (the load path on unsaved text; diagnostics),
:mod:`.completion`, :mod:`.hover`, :mod:`.navigation` (definition, references, symbols, rename), :mod:`.actions`
(code actions), :mod:`.server` (the protocol, pygls).
"""
