// Parse Mermaid diagrams with Mermaid's own parser (the `mermaid` npm package), in one process.
//
// stdin: a JSON array of diagram texts.  stdout: a JSON array, one entry per text: null when Mermaid's
// parser accepts it, else the parser's message.  Past the parser, each diagram's database is asked for the
// nodes and edges its renderer would lay out (`db.getData()`), so a text the grammar accepts but Mermaid
// cannot turn into a drawing is reported too; only the measuring of text in a browser is left out.  Exit status: 0 when every text parses, 1 when any does not,
// 2 when the input is not a JSON array of strings or Mermaid cannot be loaded.
//
// Mermaid sanitises labels with DOMPurify, which needs a DOM: under Node a jsdom window stands in for the
// browser's, installed before Mermaid is imported (DOMPurify binds to `window` when its module loads).
import { JSDOM } from 'jsdom';

const dom = new JSDOM('<!doctype html><html><body></body></html>');
globalThis.window = dom.window;
globalThis.document = dom.window.document;

async function readStdin() {
  const chunks = [];
  for await (const chunk of process.stdin) chunks.push(chunk);
  return Buffer.concat(chunks).toString('utf8');
}

let texts;
try {
  texts = JSON.parse(await readStdin());
  if (!Array.isArray(texts) || texts.some((t) => typeof t !== 'string')) throw new Error('not an array of strings');
} catch (e) {
  process.stderr.write(`mermaid_parse: stdin must be a JSON array of diagram texts (${e.message})\n`);
  process.exit(2);
}

const { default: mermaid } = await import('mermaid');
mermaid.initialize({ startOnLoad: false, securityLevel: 'strict' });

const errors = [];
for (const text of texts) {
  try {
    await mermaid.parse(text);  // throws on a syntax error (suppressErrors is off)
    const diagram = await mermaid.mermaidAPI.getDiagramFromText(text);
    if (typeof diagram.db.getData === 'function') {
      const data = diagram.db.getData();
      if (!data || !Array.isArray(data.nodes) || data.nodes.length === 0) throw new Error('Mermaid drew no nodes');
    }
    errors.push(null);
  } catch (e) {
    errors.push(String(e && e.message ? e.message : e));
  }
}
process.stdout.write(JSON.stringify(errors) + '\n');
process.exit(errors.some((e) => e !== null) ? 1 : 0);
