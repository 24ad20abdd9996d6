"""Sub-missions: a state that uses a machine written in another file (``use:`` + ``with:``).

A *sub-mission* file holds a reusable machine and the parameters it reads::

    submission: screw_operation       # instead of `mission:`; no robot, world or rate: the using mission's apply
    description: ...
    parameters:                        # what the machine reads with $name; `~` (null): no default, required
      screws: ~
      eps_t: 1.5 mm
    profiles: {...}                    # optional; merged into the using mission's (same name: same values)
    exits: [error_stop]                # optional; states of the using mission its transitions may name
    machine: {initial: ..., states: {...}, task: ..., bind: ...}

A state of a mission (or of another sub-mission) uses it with ``use: PATH`` (relative to the using
file) and ``with: {param: value | $outer_name}``.  :func:`expand_uses` resolves every ``use:`` into the
document's state tree before the shape check and the compile passes, which then see one ordinary
mission: the using state becomes a composite whose ``initial`` and ``states`` (and ``task``/``bind``,
the using state's ``bind`` winning slot by slot) are the used machine's.

Names are scoped so that nothing leaks either way: inside a used machine every ``$name`` (task and
action parameters, guards), every ``foreach in:`` and every ``foreach as:`` is rewritten —
a parameter remapped to ``$outer`` becomes the outer name; a parameter given a value (in ``with:`` or
by its default) becomes a new name ``STATE__name`` (``STATE``: the using state's path, ``.`` → ``__``)
added to the mission's ``parameters``.  Loop items (``foreach as:``) keep their names (tasks read items
by name): an item shadows the names around it, and an outer name passed in that an item of the used file
would hide is an error.  A ``$name`` the used file does not declare is an error in that file.  Positions stay true: the source map gets a :class:`~taskflow.mission.yamlsrc.Graft` per
spliced region, so a problem inside a used file is reported at that file's line and column, with
where it was used from (``Problem.via``).  A file that uses itself, directly or through others, is
refused with the chain.

A shipped sub-mission is also reachable by name from anywhere: ``use: taskflow:lib/screw_operation.yaml`` is
the file of the installed missions package (``taskflow_missions``, :data:`SHIPPED_PREFIX`), so a copy of a shipped
mission keeps working outside the package (:func:`use_path` resolves both forms, for the loader and the editor).

Bad input is bounded: a ``use:`` path must be relative and resolve inside the folder of the mission given
to taskflow (a ``taskflow:`` name inside the missions package); expansion stops at the first budget that runs out (:data:`MAX_USE_DEPTH`, :data:`MAX_USE_FILES`,
:data:`MAX_EXPANDED_STATES`, :data:`~taskflow.mission.statetree.MAX_STATE_DEPTH`), with one problem where it ran out.
"""

from __future__ import annotations

import copy
import itertools
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from taskflow.errors import MissionError, Problem
from taskflow.mission.model import YPath, has_refs
from taskflow.mission.statetree import MAX_STATE_DEPTH, count_states, loop_items, state_level, sub_machines, too_deep
from taskflow.mission.submission_file import Submission, check_submission, with_via
from taskflow.mission.yamlsrc import Graft, SourceMap, load_yaml_file, load_yaml_text
from taskflow.registry import describe_choices

MAX_USE_DEPTH = 8
"""Sub-missions nest at most this deep (a mission using a file that uses another: depth 2)."""
MAX_USE_FILES = 64
"""At most this many distinct sub-mission files per mission."""
MAX_EXPANDED_STATES = 2_000
"""At most this many states spliced in by all the ``use:`` of a mission together (a file used twice counts
twice): files that each use the next one twice would otherwise double the mission at every level."""

USE_KEYS = ("use", "with")
"""The keys of a using state that this module consumes (the shape check never sees them)."""

_NOT_WITH_USE = ("states", "initial", "final")
PARAM_REF = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")
"""A ``$name`` reference to a parameter, in a guard or a value (group 1: the name)."""


class _Scope:
    """Where a walk is: the file the states were written in, its chain of use (for cycles), how its
    parameters map to the expanded mission's (``env``; ``None``: the mission itself, whose names stay),
    and the loop items (``foreach as:``) declared around the current state — kept as written, since
    tasks and scripts read items by name."""

    def __init__(self, file: str, chain: tuple[Path, ...], env: dict[str, str] | None, known: set[str],
                 items: frozenset[str] = frozenset()) -> None:
        self.file, self.chain, self.env, self.known, self.items = file, chain, env, known, items

    def with_item(self, name: str) -> _Scope:
        return _Scope(self.file, self.chain, self.env, self.known | {name}, self.items | {name})


SHIPPED_PREFIX = "taskflow:"
"""``use: taskflow:PATH``: PATH inside the installed missions package (``taskflow_missions``), from any folder."""


def shipped_missions_dir() -> Path:
    """The folder of the missions shipped with taskflow (the package ``taskflow_missions``, installed or a checkout)."""
    import taskflow_missions

    return taskflow_missions.DIR


def use_path(target: str, using_file: str | Path) -> Path:
    """The file ``use: target`` written in ``using_file`` names: ``taskflow:PATH`` inside the shipped missions'
    folder, anything else relative to the using file's folder (an in-memory file, ``<...>``: the working folder)."""
    if target.startswith(SHIPPED_PREFIX):
        return (shipped_missions_dir() / target[len(SHIPPED_PREFIX):].lstrip("/")).resolve()
    name = str(using_file)
    base = Path(name).parent if name and not name.startswith("<") else Path.cwd()
    return (base / target).resolve()


class _Expander:
    """One expansion of one document: the problems found, the files read (each read once)."""

    def __init__(self, data: dict[str, Any], smap: SourceMap, sources: Mapping[Path, str] | None = None) -> None:
        self.data, self.smap = data, smap
        self.sources = sources or {}  # resolved path → text to read instead of the file (an editor's unsaved buffer)
        self.problems: list[Problem] = []
        self.files: dict[Path, tuple[Any, SourceMap] | MissionError] = {}
        self.root = (Path(smap.file).resolve().parent if not smap.file.startswith("<") else Path.cwd().resolve())
        self.spliced = 0  # states spliced in so far (MAX_EXPANDED_STATES)
        self.stopped = False  # a budget ran out: stop walking (one problem, not thousands)
        params = data.get("parameters")
        self.params: dict[str, Any] = params if isinstance(params, dict) else {}

    def err(self, path: YPath, message: str, hint: str = "") -> None:
        self.problems.append(self.smap.problem(path, message, hint))

    def via(self, path: YPath) -> tuple[str, ...]:
        """Where the value at ``path`` is written, as a ``via`` chain: ``FILE:LINE:COL`` and where that file was
        used from."""
        where = self.smap.problem(path, "")
        return (f"{where.file}:{where.line}:{where.col}",) + where.via

    # -- walking states ---------------------------------------------------------------------------

    def states(self, states: Any, ypath: YPath, scope: _Scope) -> None:
        if not isinstance(states, dict):
            return
        for name, state in states.items():
            if self.stopped:
                return
            if isinstance(state, dict):
                where = ypath + (name,)
                if state_level(where) > MAX_STATE_DEPTH:
                    self.stop(where, f"states nest more than {MAX_STATE_DEPTH} levels deep here (sub-missions "
                              "included)", f"a mission's states may nest at most {MAX_STATE_DEPTH} levels; flatten it")
                    return
                self.state(state, where, scope)

    def stop(self, path: YPath, message: str, hint: str) -> None:
        """A budget ran out at ``path``: report it once and walk no further."""
        self.err(path, message, hint)
        self.stopped = True

    def state(self, st: dict[str, Any], ypath: YPath, scope: _Scope) -> None:
        self.rename_state(st, ypath, scope)
        inner = scope
        fe = st.get("foreach")
        if isinstance(fe, dict) and isinstance(fe.get("as"), str):
            inner = scope.with_item(fe["as"])
        if "use" in st or "with" in st:
            self.use(st, ypath, inner)
        else:
            for sub, where in sub_machines(st, ypath):
                self.states(sub, where, inner)

    def rename_state(self, st: dict[str, Any], ypath: YPath, scope: _Scope) -> None:
        """Rewrite the ``$names`` of one state written in a used file into the mission's names."""
        if scope.env is None:
            return
        for key in ("task", "action"):
            ref = st.get(key)
            if isinstance(ref, dict) and "params" in ref:
                ref["params"] = self.rename_value(ref["params"], ypath + (key, "params"), scope)
        for i, tr in enumerate(st.get("transitions") or []):
            if isinstance(tr, dict) and isinstance(tr.get("when"), str):
                tr["when"] = self.rename_guard(tr["when"], ypath + ("transitions", i, "when"), scope)
        fe = st.get("foreach")
        if isinstance(fe, dict) and isinstance(fe.get("in"), str):
            fe["in"] = self.rename(fe["in"], ypath + ("foreach", "in"), scope)

    def rename_value(self, value: Any, ypath: YPath, scope: _Scope) -> Any:
        if isinstance(value, str) and value.startswith("$") and value[1:].isidentifier():
            return "$" + self.rename(value[1:], ypath, scope)
        if isinstance(value, dict):
            return {k: self.rename_value(v, ypath + (k,), scope) for k, v in value.items()}
        if isinstance(value, list):
            return [self.rename_value(v, ypath + (i,), scope) for i, v in enumerate(value)]
        return value

    def rename_guard(self, text: str, ypath: YPath, scope: _Scope) -> str:
        return PARAM_REF.sub(lambda m: "$" + self.rename(m.group(1), ypath, scope), text)

    def rename(self, name: str, ypath: YPath, scope: _Scope) -> str:
        """The mission's name for ``$name`` written at ``ypath`` of a used file (problems recorded)."""
        assert scope.env is not None
        if name in scope.items:
            return name
        if name not in scope.env:
            self.err(ypath, f"${name} is not a parameter of this sub-mission nor a loop item around it",
                     "declare it under `parameters:` of the file — " + describe_choices(name, sorted(scope.known)))
            return name
        if scope.env[name] in scope.items:  # the outer name would be captured by a loop item of this file
            self.err(ypath, f"${name} is the using file's ${scope.env[name]}, which the loop item "
                     f"{scope.env[name]!r} here hides", "rename that loop item (`foreach as:`)")
        return scope.env[name]

    def new_name(self, ypath: YPath, name: str) -> str:
        """The mission-wide name of ``name`` defined by the used file at state ``ypath``."""
        states = [str(p) for p in ypath[1:] if p not in ("states", "regions")]  # ("machine", "states", "a", "states", "b")
        return re.sub(r"\W", "_", "__".join(states + [name]))

    # -- one use ----------------------------------------------------------------------------------

    def use(self, st: dict[str, Any], ypath: YPath, scope: _Scope) -> None:
        target = st.pop("use", None)
        with_ = st.pop("with", None)
        if not isinstance(target, str) or not target.strip():
            self.err(ypath + (("use",) if target is not None else ("with",)),
                     "`use:` names a sub-mission file" if target is not None else "`with:` without `use:`",
                     "write `use: lib/NAME.yaml` (relative to this file)")
            return
        clash = [k for k in _NOT_WITH_USE if k in st]
        if clash:
            self.err(ypath + (clash[0],), f"a state that uses a sub-mission has no `{clash[0]}` of its own",
                     "its sub-states are the used machine's; remove it or drop `use:`")
            return
        if with_ is not None and not isinstance(with_, dict):
            self.err(ypath + ("with",), "`with:` maps the sub-mission's parameters to values or $names",
                     "write `with: {param: value}`")
            return
        shipped = target.startswith(SHIPPED_PREFIX)
        if Path(target[len(SHIPPED_PREFIX):] if shipped else target).is_absolute():
            self.err(ypath + ("use",), f"`use: {target}` is an absolute path",
                     "write it relative to the using file, inside the mission's folder (e.g. lib/NAME.yaml), or "
                     f"name a shipped one ({SHIPPED_PREFIX}lib/NAME.yaml)")
            return
        path = use_path(target, scope.file)
        home = shipped_missions_dir().resolve()
        if shipped and not path.is_relative_to(home):
            self.err(ypath + ("use",), f"`use: {target}` resolves to {path}, outside the shipped missions' folder "
                     f"{home}", f"`{SHIPPED_PREFIX}PATH` names a file of the shipped missions, e.g. "
                     f"{SHIPPED_PREFIX}lib/screw_operation.yaml")
            return
        # a file of the shipped missions may use its neighbours (it sits in the package, not the mission's folder)
        if not shipped and not path.is_relative_to(self.root) and not (
                Path(scope.file).resolve().is_relative_to(home) and path.is_relative_to(home)):
            self.err(ypath + ("use",), f"`use: {target}` resolves to {path}, outside the mission's folder {self.root}",
                     "a sub-mission sits in the folder of the mission given to taskflow or below it (e.g. lib/), "
                     "so that the folder holds everything the mission runs: copy the file there, or name a shipped "
                     f"one from anywhere ({SHIPPED_PREFIX}lib/NAME.yaml)")
            return
        if path in scope.chain:
            names = [str(p) for p in scope.chain[scope.chain.index(path):]] + [str(path)]
            self.err(ypath + ("use",), f"a cycle of sub-missions: {' → '.join(names)}",
                     "a file may not use itself, directly or through the files it uses")
            return
        if len(scope.chain) > MAX_USE_DEPTH:
            self.stop(ypath + ("use",), f"sub-missions nest more than {MAX_USE_DEPTH} deep here "
                      f"({' → '.join(p.name for p in scope.chain + (path,))})",
                      f"a mission may nest at most {MAX_USE_DEPTH} levels of `use:`")
            return
        if path not in self.files and len(self.files) >= MAX_USE_FILES:
            self.stop(ypath + ("use",), f"a mission may use at most {MAX_USE_FILES} sub-mission files; this is one more",
                      "merge some of them")
            return
        loaded = self.read(path, target, ypath)
        if loaded is None:
            return
        doc, inner_map = loaded
        self.spliced += count_states(doc.machine.get("states"))
        if self.spliced > MAX_EXPANDED_STATES:
            self.stop(ypath + ("use",), f"the sub-missions used expand to more than {MAX_EXPANDED_STATES} states "
                      f"(this use brings the total to {self.spliced})",
                      f"a mission's `use:` may splice in at most {MAX_EXPANDED_STATES} states in all (a file used "
                      "twice counts twice): use fewer, or smaller, sub-missions")
            return
        via = self.via(ypath + ("use",))
        env = self.bind_parameters(doc, inner_map, with_ or {}, ypath, scope, via)
        if env is None:
            return
        for kind, named in doc.profiles.items():  # merged into the mission's
            profiles = self.data.setdefault("profiles", {})
            if not isinstance(profiles, dict):
                break
            mine = profiles.setdefault(kind, {})
            for pname, values in named.items():
                if pname in mine and mine[pname] != values:
                    self.problems.append(with_via(inner_map.problem(
                        ("profiles", kind, pname), f"profile {kind}.{pname} is also defined by the using mission, "
                        "with other values", "rename one of them (profiles share one namespace)"), via))
                elif pname not in mine:
                    mine[pname] = copy.deepcopy(values)
                    self.smap.graft(Graft(("profiles", kind, pname), inner_map, ("profiles", kind, pname), via))
        machine = copy.deepcopy(doc.machine)
        if "task" in machine and "task" in st:
            self.err(ypath + ("task",), "both this state and the used machine give a `task`", "keep one")
            return
        for key in ("initial", "states", "task"):
            if key in machine:
                st[key] = machine[key]
                self.smap.graft(Graft(ypath + (key,), inner_map, ("machine", key), via))
        if isinstance(machine.get("bind"), dict):
            bind = st.get("bind")
            own: dict[str, Any] = bind if isinstance(bind, dict) else {}
            for slot in machine["bind"]:
                if slot not in own:
                    self.smap.graft(Graft(ypath + ("bind", slot), inner_map, ("machine", "bind", slot), via))
            st["bind"] = {**machine["bind"], **own}
        self.smap.uses[ypath] = target
        inner = _Scope(str(path), scope.chain + (path,), env, set(doc.parameters))
        ref = machine.get("task")
        if isinstance(ref, dict) and "params" in ref:  # the used machine's own task, in its names
            ref["params"] = self.rename_value(ref["params"], ypath + ("task", "params"), inner)
        self.states(st.get("states"), ypath + ("states",), inner)

    def read(self, path: Path, target: str, ypath: YPath) -> tuple[Submission, SourceMap] | None:
        """The sub-mission at ``path``, shape-checked (problems recorded, None when unusable)."""
        if path not in self.files:
            try:
                if path in self.sources:
                    data, inner_map = load_yaml_text(self.sources[path], str(path))
                else:
                    data, inner_map, _ = load_yaml_file(path)
                self.files[path] = (data, inner_map)
            except MissionError as exc:
                self.files[path] = exc
        got = self.files[path]
        if isinstance(got, MissionError):
            first = got.problems[0]
            if first.line == 0:  # the file itself: missing, a directory, unreadable
                near = (sorted(f.name for f in itertools.islice(path.parent.glob("*.yaml"), 500))
                        if path.parent.is_dir() else [])  # a few hundred names are enough for a "did you mean"
                hint = ("the name is a file of the shipped missions' folder" if target.startswith(SHIPPED_PREFIX)
                        else "the path is relative to the file that uses it")
                if first.message == "no such file" and near:
                    hint += "; " + describe_choices(path.name, near)
                if first.message == "no such file" and not target.startswith(SHIPPED_PREFIX):
                    home = shipped_missions_dir()
                    if (home / target).is_file():  # a copied shipped mission: its sub-mission is in the package
                        hint += f"; taskflow ships {target}: write `use: {SHIPPED_PREFIX}{target}` to use it from anywhere"
                self.err(ypath + ("use",), f"sub-mission {target!r}: {first.message} ({path})", hint)
            else:
                self.problems.extend(with_via(p, self.via(ypath + ("use",))) for p in got.problems)
            return None
        data, inner_map = got
        doc, problems = check_submission(data, inner_map, self.via(ypath + ("use",)))
        self.problems += problems
        return None if doc is None else (doc, inner_map)

    def bind_parameters(self, doc: Submission, inner_map: SourceMap, with_: dict[str, Any], ypath: YPath,
                        scope: _Scope, via: tuple[str, ...]) -> dict[str, str] | None:
        """The used file's names → the mission's, adding the parameters given a value; None: reported."""
        env: dict[str, str] = {}
        ok = True
        for key in with_:
            if key not in doc.parameters:
                self.err(ypath + ("with", key), f"{key!r} is not a parameter of sub-mission {doc.submission!r}",
                         describe_choices(str(key), list(doc.parameters)))
                ok = False
        for name, default in doc.parameters.items():
            if name in with_:
                value = with_[name]
                if isinstance(value, str) and value.startswith("$") and value[1:].isidentifier():
                    ref = value[1:]
                    if ref not in scope.known:
                        self.err(ypath + ("with", name), f"${ref} is not a parameter or loop item here",
                                 describe_choices(ref, sorted(scope.known)))
                        ok = False
                        continue
                    env[name] = ref if scope.env is None else self.rename(ref, ypath + ("with", name), scope)
                    continue
                if has_refs(value):
                    self.err(ypath + ("with", name), "`with:` gives a value or one $name, not a value holding $names",
                             "parameters are not resolved inside other parameters: pass the list as a parameter")
                    ok = False
                    continue
                where: Graft = Graft(("parameters",), self.smap, ypath + ("with", name))
            elif default is None:
                self.err(ypath + ("use",), f"sub-mission {doc.submission!r} needs parameter {name!r} (it has no default)",
                         "give it in `with:`")
                ok = False
                continue
            else:
                value = default
                where = Graft(("parameters",), inner_map, ("parameters", name), via)
            scoped = self.new_name(ypath, name)
            if scoped in self.params:
                self.err(ypath + ("use",), f"parameter {name!r} of the sub-mission would be named {scoped!r}, "
                         "which the mission already has", "rename that parameter or the state")
                ok = False
                continue
            self.params[scoped] = copy.deepcopy(value)
            self.smap.graft(Graft(("parameters", scoped), where.smap, where.base, where.via))
            env[name] = scoped
        return env if ok else None


def expand_uses(data: dict[str, Any], smap: SourceMap, sources: Mapping[Path, str] | None = None) -> dict[str, Any]:
    """``data`` with every ``use:`` resolved into its state tree (a copy; ``data`` is left as it was).
    Grafts and uses are recorded in ``smap``; every problem found is raised together.  ``sources`` maps a
    resolved file path to the text to read for it instead of the file (the language server's open buffers)."""
    machine = data.get("machine")
    if not isinstance(machine, dict):
        return data
    deep = too_deep(machine.get("states"), ("machine", "states"))
    if deep is not None:
        raise MissionError([smap.problem(deep, f"states nest more than {MAX_STATE_DEPTH} levels deep here",
                                         f"a mission's states may nest at most {MAX_STATE_DEPTH} levels; flatten it")])
    if not _has_use(machine.get("states")):
        return data
    data = copy.deepcopy(data)
    ex = _Expander(data, smap, sources)
    if ex.params is not data.get("parameters"):
        data["parameters"] = ex.params
    top = Path(smap.file).resolve() if not smap.file.startswith("<") else Path.cwd() / smap.file
    known = set(ex.params) | loop_items(data["machine"].get("states"))
    ex.states(data["machine"].get("states"), ("machine", "states"), _Scope(smap.file, (top,), None, known))
    if ex.problems:
        raise MissionError(ex.problems)
    return data


def _has_use(states: Any) -> bool:
    return isinstance(states, dict) and any(
        isinstance(st, dict) and (any(k in st for k in USE_KEYS) or any(_has_use(sub) for sub, _ in sub_machines(st, ())))
        for st in states.values())
