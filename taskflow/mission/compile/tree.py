"""Compile pass: the state tree — one :class:`~taskflow.mission.model.StateNode` per state, with its effective
task and bindings (inherited down the tree, overridden where a state gives its own), its loop, action
and final outcome; then the catalogue of what the mission's tasks and world publish."""

from __future__ import annotations

from taskflow.mission.compile.context import Compilation
from taskflow.mission.contracts import task_problem
from taskflow.mission.model import Loop, StateNode, YPath
from taskflow.mission.schema import Machine, Region, State
from taskflow.registry import TASKS, RegistryError, UnknownName, describe_choices


def build_tree(c: Compilation) -> StateNode:
    root = StateNode("", "", None, ("machine",))
    _build(c, root, c.spec.machine, ("machine",))
    return root


def _build(c: Compilation, node: StateNode, spec: State | Machine | Region, ypath: YPath) -> None:
    parent = node.parent
    if spec.task is not None:  # the task: inherited unless given
        tname, tparams = (spec.task, {}) if isinstance(spec.task, str) else (spec.task.name, spec.task.params)
        tpath = ypath + ("task",) if isinstance(spec.task, str) else ypath + ("task", "name")
        try:
            cls = TASKS.get(tname)
            mismatch = task_problem(cls, c.robot, c.world)
            if mismatch is not None:
                c.err(tpath, *mismatch)
            node.task_cls, node.task_params = cls, dict(tparams)
            node.task_ypath = ypath + ("task",)
        except UnknownName as exc:
            c.err(tpath, f"unknown task {tname!r}", f"{describe_choices(tname, exc.valid)}; `taskflow list tasks` says what each does")
        except RegistryError as exc:
            c.err(tpath, str(exc))
    elif parent is not None:
        node.task_cls, node.task_params, node.task_ypath = parent.task_cls, parent.task_params, parent.task_ypath
    node.bind = dict(parent.bind) if parent is not None else {}
    for slot, ref in spec.bind.items():
        node.bind[slot] = ("", ref, ypath + ("bind", slot))
    if isinstance(spec, State):
        _state_keys(c, node, spec, ypath)
    if isinstance(spec, State) and "regions" in spec.model_fields_set and not spec.regions:
        c.err(ypath + ("regions",), "`regions:` is empty: a parallel state needs at least two regions",
              "give it two or more regions, or drop `regions:` (one region is an ordinary composite)")
    if isinstance(spec, State) and spec.regions:
        _build_regions(c, node, spec, ypath)
    elif spec.states:
        if spec.initial is None:
            c.err(ypath, "a state with sub-states needs `initial`", f"one of: {', '.join(spec.states)}")
        elif spec.initial not in spec.states:
            c.err(ypath + ("initial",), f"initial state {spec.initial!r} is not a sub-state",
                  describe_choices(spec.initial, list(spec.states)))
        node.initial = spec.initial
        for name, child_spec in spec.states.items():
            if "." in name or not name.replace("_", "a").replace("-", "a").isalnum():
                c.err(ypath + ("states", name), f"state name {name!r} must be letters, digits, '_' or '-'")
                continue
            child = StateNode(name, f"{node.path}.{name}" if node.path else name, node, ypath + ("states", name),
                              depth=node.depth + 1)
            node.children[name] = child
            c.states[child.path] = child
            _build(c, child, child_spec, ypath + ("states", name))
    elif isinstance(spec, State) and spec.initial is not None:
        c.err(ypath + ("initial",), "`initial` given but the state has no sub-states")
    elif isinstance(spec, (Machine, Region)):
        c.err(ypath + ("states",), f"the {'machine' if isinstance(spec, Machine) else 'region'} has no states",
              "declare at least one state and a final one")


def _build_regions(c: Compilation, node: StateNode, spec: State, ypath: YPath) -> None:
    """A parallel state: one region node per ``regions`` entry (each a composite that owns command parts)."""
    node.parallel = True
    for key in ("states", "initial", "foreach", "history"):
        if getattr(spec, key):
            c.err(ypath + (key,), f"a state with `regions` runs them in parallel; it cannot also have `{key}`",
                  "put the sub-states inside a region")
    if len(spec.regions) < 2:
        c.err(ypath + ("regions",), "a parallel state needs at least two regions",
              "one region is an ordinary composite: use `states` and `initial`")
    parts = c.robot.command_keys
    enclosing = node.region
    owner: dict[str, str] = {}
    for name, rspec in spec.regions.items():
        rpath = ypath + ("regions", name)
        if "." in name or not name.replace("_", "a").replace("-", "a").isalnum():
            c.err(rpath, f"region name {name!r} must be letters, digits, '_' or '-'")
            continue
        for i, part in enumerate(rspec.owns):
            if part not in parts:
                c.err(rpath + ("owns", i), f"the robot's command has no part {part!r}",
                      describe_choices(part, list(parts)))
            elif part in owner:
                c.err(rpath + ("owns", i), f"regions {owner[part]!r} and {name!r} both drive {part!r}",
                      "each command part is driven by one region; let the other own different parts, or none")
            elif enclosing is not None and part not in (enclosing.owns or ()):
                c.err(rpath + ("owns", i), f"region {name!r} is inside region {enclosing.path!r}, which does not own "
                      f"{part!r}", f"parts it owns: {', '.join(enclosing.owns or ()) or '(none)'}")
            else:
                owner[part] = name
        child = StateNode(name, f"{node.path}.{name}" if node.path else name, node, rpath, depth=node.depth + 1)
        child.owns = tuple(rspec.owns)
        node.children[name] = child
        c.states[child.path] = child
        _build(c, child, rspec, rpath)
    rules: list[tuple[str, dict[str, str]]] = []
    for outcome, need in spec.outcome_map.items():
        for region in need:
            if region not in spec.regions:
                c.err(ypath + ("outcome_map", outcome, region), f"{region!r} is not a region of this state",
                      describe_choices(region, list(spec.regions)))
        rules.append((outcome, dict(need)))
    node.outcome_map = tuple(rules)


def _state_keys(c: Compilation, node: StateNode, spec: State, ypath: YPath) -> None:
    node.history = spec.history
    node.use = c.smap.uses.get(ypath)
    node.final = "succeeded" if spec.final is True else (spec.final or None)
    if spec.foreach is not None:
        fe = spec.foreach
        items = c.spec.parameters.get(fe.in_)
        required = fe.required(len(items)) if isinstance(items, list) and items else 0  # the list is checked later
        node.loop = Loop(fe.in_, fe.as_, fe.on_failure, required, str(fe.require), *_retry_of(spec))
    if spec.action is not None:
        node.action = (spec.action.name, dict(spec.action.params))
    if spec.final and (spec.states or spec.task or spec.transitions or spec.action):
        c.err(ypath + ("final",), "a final state ends its machine: it has no task, action, sub-states or transitions",
              "remove them or drop `final`")
    if spec.history and not spec.states and not spec.regions:
        c.err(ypath + ("history",), "history only applies to a state with sub-states")
    if spec.outcome_map and not spec.regions:
        c.err(ypath + ("outcome_map",), "`outcome_map` only applies to a state with `regions`")
    if spec.foreach is not None and not spec.states:
        c.err(ypath + ("foreach",), "foreach repeats a sub-machine: give the state `states` and `initial`")


def _retry_of(spec: State) -> tuple[int, tuple[str, ...]]:
    """A ``foreach``'s further attempts and the final sub-states they follow: those ``on`` names (the loader
    checks each names a final that does not succeed), by default every ``failed`` one."""
    retry = spec.foreach.retry if spec.foreach is not None else None
    if retry is None or retry.times == 0:
        return 0, ()
    finals = {name: ("succeeded" if st.final is True else st.final) for name, st in spec.states.items() if st.final}
    if retry.on is None:
        return retry.times, tuple(name for name, outcome in finals.items() if outcome == "failed")
    return retry.times, tuple(name for name in retry.on if finals.get(name) not in (None, "succeeded"))


def catalogue(c: Compilation, root: StateNode) -> tuple[dict[str, str], set[str]]:
    """Every metric (→ unit) and every event the mission's world, actions and tasks publish, and the events
    the mission declares for its operator (``events:``)."""
    world = c.world
    units: dict[str, str] = dict(world.metrics)
    events: set[str] = set(world.events) | set(c.spec.events)
    for evs in world.actions.values():
        events.update(evs)
    for n in root.walk():
        if n.task_cls is not None:
            units.update(n.task_cls.metrics)
            events.update(n.task_cls.events)
    return units, events


def check_region_metrics(c: Compilation, root: StateNode) -> None:
    """Two regions' tasks must not publish a metric of the same name: a guard, the trace and the summary
    could not tell which region's value they read."""
    for p in root.walk():
        if not p.parallel:
            continue
        publisher: dict[str, str] = {}
        for region in p.children.values():
            mine = {m for n in region.walk() if n.is_leaf and n.task_cls is not None for m in n.task_cls.metrics}
            for m in sorted(mine):
                if m in publisher:
                    c.err(region.ypath, f"regions {publisher[m]!r} and {region.name!r} both run tasks that publish the "
                          f"metric {m!r}", "give each region tasks with their own metrics (a task inherited from above "
                          "the parallel state runs in every region: give the regions their own `task`)")
                else:
                    publisher[m] = region.name


def metrics_under(c: Compilation, node: StateNode) -> dict[str, str]:
    """The metrics a guard on ``node`` may read: the world's, those of every task at or below it, and —
    inside a parallel region — those of every task of the regions concurrent with it (:func:`sibling_metrics`)."""
    units = dict(c.world.metrics)
    for n in node.walk():
        if n.task_cls is not None:
            units.update(n.task_cls.metrics)
    for m, (unit, _) in sibling_metrics(node).items():
        units.setdefault(m, unit)
    return units


def sibling_metrics(node: StateNode) -> dict[str, tuple[str, str]]:
    """Metric → (unit, region publishing it) for every task in a region concurrent with ``node``: the sibling
    regions of each region ``node`` lies in (they are active whenever ``node`` is).  Empty outside regions."""
    out: dict[str, tuple[str, str]] = {}
    region = node.region
    while region is not None:
        parallel = region.parent
        assert parallel is not None
        for sibling in parallel.children.values():
            if sibling is region:
                continue
            for n in sibling.walk():
                if n.task_cls is not None:
                    for m, unit in n.task_cls.metrics.items():
                        out.setdefault(m, (unit, sibling.path))
        region = parallel.region
    return out


def check_region_names(c: Compilation, root: StateNode) -> None:
    """A region may not have the name of a state its transitions could name: a transition inside the region
    finds a bare name in the nearest enclosing machine first, so a region ``done`` next to a state ``done``
    would take ``to: done`` from inside it to the region (which no transition may enter) instead."""
    for p in root.walk():
        if not p.parallel:
            continue
        for region in p.children.values():
            scope = p.parent
            while scope is not None:
                other = scope.children.get(region.name)
                if other is not None:
                    c.err(region.ypath, f"region {region.name!r} has the name of state {other.path!r}, which it hides "
                          "from the transitions inside it (a bare name is looked up in the nearest machine first)",
                          "rename the region")
                    break
                scope = scope.parent
