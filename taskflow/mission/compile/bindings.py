"""Compile passes: what each state binds — profiles (every slot of every leaf's task filled, every
profile valid for its kind) and parameters (task and action parameters valid for every ``foreach``
item, loops over real lists with rules that can hold)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from taskflow.mission.compile.context import Compilation
from taskflow.mission.data import not_finite
from taskflow.mission.diagnostics import clean_loc
from taskflow.mission.model import StateNode, UnknownRef, YPath, resolve_refs, with_model_defaults
from taskflow.mission.schema import State
from taskflow.registry import describe_choices


def profile_kind(model: type[BaseModel], slot: str) -> str:
    """The ``profiles:`` section a slot's profile comes from (the model's ``kind``, else the slot)."""
    return getattr(model, "kind", None) or slot


def bind_profiles(c: Compilation, root: StateNode) -> None:
    profiles = c.spec.profiles
    kinds: dict[str, type[BaseModel]] = {}  # every profile kind a task uses, with its model
    for n in root.walk():
        if n.task_cls is not None:
            for slot, model in n.task_cls.slots.items():
                kinds.setdefault(profile_kind(model, slot), model)
    for kind, named in profiles.items():
        if kind not in kinds:
            c.err(("profiles", kind), f"no task of this mission uses profiles of kind {kind!r}",
                  describe_choices(kind, list(kinds)))
            continue
        for pname, values in named.items():
            c.validate_model(kinds[kind], values, ("profiles", kind, pname))
    for n in root.walk():
        # a bind must name a slot some task at or below it uses
        used_slots = {s for d in n.walk() if d.task_cls is not None for s in d.task_cls.slots}
        for slot in c.spec_of(n).bind:
            if slot not in used_slots:
                c.err(n.ypath + ("bind", slot), f"no task at or below this state has a profile slot {slot!r}",
                      describe_choices(slot, sorted(used_slots)))
        if n.is_leaf and n.task_cls is not None:
            _bind_leaf(c, n, profiles)


def _bind_leaf(c: Compilation, n: StateNode, profiles: dict[str, dict[str, dict[str, Any]]]) -> None:
    assert n.task_cls is not None
    defaults = n.task_cls.default_profiles()
    for slot, model in n.task_cls.slots.items():
        kind = profile_kind(model, slot)
        if slot not in n.bind:
            if slot in defaults:  # a slot the mission binds nothing to holds its model's defaults
                n.profiles[slot] = defaults[slot]
            else:
                c.err(n.ypath, f"task {n.task_cls.name!r} needs a {kind!r} profile in slot {slot!r}",
                      f"add `bind: {{{slot}: NAME}}` here or on a parent; defined {kind} profiles: "
                      f"{', '.join(profiles.get(kind, {})) or '(none)'}")
            continue
        _, ref, where = n.bind[slot]
        if isinstance(ref, dict):
            m = c.validate_model(model, ref, where)
        elif ref not in profiles.get(kind, {}):
            c.err(where, f"unknown {kind} profile {ref!r}", describe_choices(ref, list(profiles.get(kind, {}))))
            continue
        else:
            try:
                m = model.model_validate(profiles[kind][ref])
            except ValidationError:
                m = None  # reported at the profile itself
        if m is not None:
            n.profiles[slot] = m


def check_parameters(c: Compilation, root: StateNode) -> None:
    for name, value in c.spec.parameters.items():  # NaN/inf mean nothing to a task, a guard or a loop
        bad = not_finite(value)
        if bad is not None:
            c.err(("parameters", name), f"parameter {name!r} holds {bad!r}", "a mission parameter's numbers are finite")
    for n in root.walk():
        if n.action is not None:
            _check_action(c, n)
        spec = c.spec_of(n)
        if isinstance(spec, State) and spec.foreach is not None:
            _check_loop(c, n, spec)
        if n.is_leaf and n.task_cls is not None and _refs_resolve(c, n, n.task_params, n.task_ypath + ("params",),
                                                                  c.mission_data.samples()):
            validate_every_item(c, n, n.task_cls.Params, n.task_params, n.task_ypath + ("params",),
                                f"task {n.task_cls.name!r}")


def _check_action(c: Compilation, n: StateNode) -> None:
    assert n.action is not None
    name, aparams = n.action
    world = c.world
    if name not in world.actions:
        c.err(n.ypath + ("action", "name"), f"world {world.name!r} has no action {name!r}",
              describe_choices(name, list(world.actions)))
    if _refs_resolve(c, n, aparams, n.ypath + ("action", "params")):
        model = world.action_params.get(name)
        if model is not None:
            validate_every_item(c, n, model, aparams, n.ypath + ("action", "params"), f"action {name!r}")


def _check_loop(c: Compilation, n: StateNode, spec: State) -> None:
    fe, params = spec.foreach, c.spec.parameters
    assert fe is not None
    where = n.ypath + ("foreach", "in")
    if fe.in_ not in params:
        c.err(where, f"unknown list parameter {fe.in_!r}", describe_choices(fe.in_, list(params)))
    elif not isinstance(params[fe.in_], list) or not params[fe.in_]:
        c.err(where, f"parameter {fe.in_!r} must be a non-empty list to iterate over")
    else:
        n_items = len(params[fe.in_])
        if fe.required(n_items) > n_items:
            c.err(n.ypath + ("foreach", "require"), f"require {fe.require!r}: the list {fe.in_!r} has only {n_items} items",
                  f"require at most {n_items}, or 'all'")
        if fe.on_failure == "stop" and fe.require != "all":
            c.err(n.ypath + ("foreach", "require"), f"require {fe.require!r} with on_failure: stop — the first failed "
                  "item ends the loop, so the rule could never let one fail", "add `on_failure: continue`, or drop `require`")
    if fe.retry is not None and fe.retry.on is not None:
        _check_retry_on(c, n, fe.retry.on)
    if fe.as_ in params:
        c.err(n.ypath + ("foreach", "as"), f"{fe.as_!r} would hide the mission parameter of that name",
              "choose another item name")


def _check_retry_on(c: Compilation, n: StateNode, on: list[str]) -> None:
    """Each name of a ``retry: {on: [...]}`` is a final sub-state of the loop that does not succeed."""
    retryable = [name for name, child in n.children.items() if child.final not in (None, "succeeded")]
    for i, name in enumerate(on):
        where = n.ypath + ("foreach", "retry", "on", i)
        child = n.children.get(name)
        if child is not None and child.final == "succeeded":
            c.err(where, f"retry on {name!r}: that final state succeeds, there is nothing to retry",
                  "name a final state whose outcome is failed or aborted" + (f": {', '.join(retryable)}" if retryable else ""))
        elif child is None or child.final is None:
            what = "is not a final state of" if child is not None else "names no final state of"
            c.err(where, f"retry on {name!r} {what} the sub-machine of {n.path!r}",
                  describe_choices(name, retryable) if retryable else "give the sub-machine a final state that fails")


def _first_items(c: Compilation, n: StateNode) -> dict[str, Any]:
    """Every enclosing foreach item at its list's first value (None where the list is not one)."""
    params = c.spec.parameters
    return {item: (params[lst][0] if isinstance(params.get(lst), list) and params[lst] else None)
            for item, lst in n.scope_items()}


def _refs_resolve(c: Compilation, n: StateNode, raw: dict[str, Any], where: YPath,
                  data: dict[str, Any] | None = None) -> bool:
    """Whether every ``$reference`` in ``raw`` names a mission parameter or an enclosing foreach item (or,
    given ``data``, the mission's data keys — task parameters only: ``$data.<key>``)."""
    scope = _first_items(c, n)
    try:
        resolve_refs(raw, c.spec.parameters, scope, data=data)
    except UnknownRef as exc:
        valid = ["$" + k for k in list(c.spec.parameters) + list(scope) + ["data." + k for k in data or ()]]
        c.err(where + exc.path, f"unknown reference ${exc.name}", describe_choices("$" + exc.name, valid))
        return False
    return True


def validate_every_item(c: Compilation, n: StateNode, model: type[BaseModel], raw: dict[str, Any], where: YPath,
                        what: str) -> None:
    """Validate ``raw`` (which may hold ``$references``) against ``model`` with the first item of every
    enclosing foreach, then with every other item of each list (the others at their first item)."""
    params = c.spec.parameters
    first = _first_items(c, n)
    data = c.mission_data.samples()
    if c.validate_model(model, resolve_refs(raw, params, first, data=data), where) is None:
        return
    for item, lst in n.scope_items():
        values = params.get(lst)
        for idx, value in enumerate(values if isinstance(values, list) else []):
            if idx == 0:
                continue
            try:
                model.model_validate(with_model_defaults(model, resolve_refs(raw, params, {**first, item: value},
                                                                             data=data)))
            except ValidationError as exc:
                err = exc.errors()[0]
                loc = ".".join(str(x) for x in clean_loc(tuple(err["loc"])))
                c.err(("parameters", lst, idx), f"item {idx} of {lst!r} does not fit {what} "
                      f"(state {n.path!r}): {loc}: {err['msg']}", "make every item the same shape as the first")
                break
