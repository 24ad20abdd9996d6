"""Typed keys of the run's shared memory: one definition names an entry; reads of a missing entry say which."""

from __future__ import annotations

import pytest
from taskflow_tasks.screw.data import PID_B, Q_NOM
from taskflow_tasks.viki.hyco import MEM_OBJECT

from taskflow.api import MemoryKey, sequence


def test_a_key_reads_and_writes_its_entry_by_its_whole_name() -> None:
    key: MemoryKey[list[int]] = MemoryKey("test.items", sequence())
    memory: dict = {}
    assert key.get(memory) is None and not key.present(memory)
    assert key.setdefault(memory, [1]) == [1]
    key(memory).append(2)
    assert memory == {"test.items": [1, 2]} and key.present(memory)
    key.set(memory, [3])
    assert key(memory) == [3]


def test_reading_a_missing_entry_names_it() -> None:
    with pytest.raises(KeyError, match="shared memory has no 'viki.object' yet"):
        MEM_OBJECT({})


def test_the_shipped_keys_are_namespaced_by_their_owner_and_distinct() -> None:
    names = [PID_B.name, Q_NOM.name, MEM_OBJECT.name]
    assert names == ["screw.pid_b", "screw.q_nom", "viki.object"]
