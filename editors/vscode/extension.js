// The VS Code client of `taskflow lsp`: starts the server over stdio for the YAML files that are missions.
const vscode = require("vscode");
const { LanguageClient } = require("vscode-languageclient/node");

let client;

function activate(context) {
  const config = vscode.workspace.getConfiguration("taskflow");
  const [command, ...args] = config.get("command");
  const patterns = config.get("files");
  client = new LanguageClient(
    "taskflow",
    "taskflow missions",
    { command, args, transport: 0 /* stdio */ },
    { documentSelector: patterns.map((pattern) => ({ scheme: "file", language: "yaml", pattern })) },
  );
  context.subscriptions.push(client);
  return client.start();
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
