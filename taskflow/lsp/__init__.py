"""``taskflow lsp``: mission authoring in any editor through the Language Server Protocol (docs/editors.md).

:mod:`.document` (where things are in the text), :mod:`.analysis` (the load path on unsaved text; diagnostics),
:mod:`.completion`, :mod:`.hover`, :mod:`.navigation` (definition, references, symbols, rename), :mod:`.actions`
(code actions), :mod:`.context` (what a feature reads: buffers, position conversions), :mod:`.server` (the
protocol, pygls).

May import: ``mission`` (the load path it runs on unsaved text), ``catalogue`` (what hover and completion say
about registered names) and the public modules; nothing imports it but ``cli`` (``taskflow lsp``).
"""
