"""The explorer's memo of firings (``_Explorer.fire_from``) gives what firing afresh gives.

``fire_from`` fires a transition once per clock-free part of a configuration, with every clock running, reads off
what the firing did to each clock and applies that to every configuration sharing the part.  Here every step of
the models of generated machines (history, ``foreach`` with ``retry``, parallel regions, ``since: first_entry``
clocks) is fired again the plain way — the configuration thawed with its own clocks, :meth:`_Explorer.fire` — and
must give the same configuration and records; and each transition a leaf set can fire is found by the memoized
``enabled`` exactly when the direct reading of its clock says so.
"""

from __future__ import annotations

import pytest
from machines import generate

from taskflow.mission.loader import load_mission_text
from taskflow.mission.model import EventTransition, GuardTransition, TimeoutTransition
from taskflow.verify.model import StateBudgetExceeded, _Explorer, _ms, build_model

pytestmark = pytest.mark.machine


def _enabled_directly(ex: _Explorer, c):  # type: ignore[no-untyped-def]
    """The enabled transitions read straight off the clocks (the rule ``enabled`` memoizes)."""
    out = []
    seen: set[int] = set()
    events = ex.events_possible(c)
    for leaf in c.leaves:
        for tr in ex.tables.get(leaf, ()):
            if tr.index in seen:
                continue
            seen.add(tr.index)
            if isinstance(tr, TimeoutTransition):
                if ex.clock(c, tr.since.path, tr.since_first) * ex.qms >= _ms(tr.after):
                    out.append(tr.index)
            elif isinstance(tr, GuardTransition):
                need = int(_ms(tr.dwell) / ex.qms + 1e-9) if tr.dwell > 0.0 else 0
                if need == 0 or ex.clock(c, tr.source.path, False) >= need:
                    out.append(tr.index)
            elif isinstance(tr, EventTransition) and tr.event in events[0] | events[1]:
                out.append(tr.index)
    return out


def test_memoized_firings_equal_fresh_firings() -> None:
    checked = machines = clocks_changed = 0
    for seed in range(60):
        mission = load_mission_text(generate(seed), f"generated_{seed}.yaml")
        try:
            model = build_model(mission, budget=3_000)
        except StateBudgetExceeded:
            continue
        machines += 1
        fresh = _Explorer(mission, None)
        for c in model.configs:
            if c.outcome is not None:
                continue
            enabled, _ = fresh.enabled(c)
            assert [tr.index for tr, _, _ in enabled] == _enabled_directly(fresh, c)
            for tr, cause, _ in enabled:
                w = fresh.thaw(c)
                fresh.fire(w, tr, cause)
                memo_config, memo_records = fresh.fire_from(c, tr, cause)
                assert memo_config == fresh.freeze(w), (seed, c.describe(), tr.label)
                assert memo_records == tuple(w.records)
                clocks_changed += memo_config.clocks != c.clocks
                checked += 1
    assert machines >= 30 and checked >= 5_000, (machines, checked)
    assert clocks_changed >= checked // 4  # the clock effects are exercised, not only left alone
