"""The nested machine as a Mermaid ``stateDiagram-v2`` or a Graphviz ``dot`` digraph."""

from __future__ import annotations

from .model import CompiledMission, StateNode


def _mid(node: StateNode) -> str:
    return node.path.replace(".", "__").replace("-", "_")


def to_mermaid(m: CompiledMission) -> str:
    lines = ["stateDiagram-v2", f"    %% {m.name}"]

    def block(node: StateNode, indent: str) -> None:
        if node.children:
            lines.append(f"{indent}[*] --> {_mid(node.children[node.initial])}")  # type: ignore[index]
        for child in node.children.values():
            label = child.name
            if child.task_cls is not None and child.is_leaf and not child.final:
                label += f" ({child.task_cls.name})"
            if child.loop:
                label += f" [foreach {child.loop.item} in {child.loop.items}]"
            if child.history:
                label += " [H]"
            if child.use:
                label += f" [use {child.use}]"
            if child.final:
                label += f" = {child.final}"
            if child.children:
                lines.append(f'{indent}state "{label}" as {_mid(child)} {{')
                block(child, indent + "    ")
                lines.append(f"{indent}}}")
            else:
                lines.append(f'{indent}state "{label}" as {_mid(child)}')
            if child.final:
                lines.append(f"{indent}{_mid(child)} --> [*]")

    block(m.root, "    ")
    for t in m.transitions:
        label = t.label.replace(":", "∶").replace("<", "&lt;").replace(">", "&gt;")
        lines.append(f"    {_mid(t.source)} --> {_mid(t.target)} : {label}")
    return "\n".join(lines)


def to_dot(m: CompiledMission) -> str:
    lines = [f'digraph "{m.name}" {{', "    compound=true; rankdir=LR; node [shape=box, style=rounded];"]

    def block(node: StateNode, indent: str) -> None:
        for child in node.children.values():
            if child.children:
                lines.append(f'{indent}subgraph "cluster_{_mid(child)}" {{')
                extra = [f"use {child.use}"] if child.use else []
                if child.loop:
                    extra.append(f"foreach {child.loop.item} in {child.loop.items}")
                if child.history:
                    extra.append("history")
                lines.append(f'{indent}    label="{child.name}{" (" + ", ".join(extra) + ")" if extra else ""}";')
                lines.append(f'{indent}    "{_mid(child)}" [shape=point];')
                block(child, indent + "    ")
                lines.append(f"{indent}}}")
            else:
                shape = ', shape=doublecircle' if child.final else ""
                task = f"\\n({child.task_cls.name})" if child.task_cls is not None and not child.final else ""
                fin = f"\\n= {child.final}" if child.final else ""
                lines.append(f'{indent}"{_mid(child)}" [label="{child.name}{task}{fin}"{shape}];')

    block(m.root, "    ")
    for t in m.transitions:
        label = t.label.replace('"', "'")
        lines.append(f'    "{_mid(t.source)}" -> "{_mid(t.target)}" [label="{label}"];')
    lines.append("}")
    return "\n".join(lines)
