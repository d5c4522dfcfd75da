"""Restructuring keeps behaviour: plans and lockstep traces hash as before (see the module
tests/behaviour_hashes.py for the instance set and how to regenerate after an intended change)."""

from __future__ import annotations

import json

import pytest
from behaviour_hashes import GOLDEN, compute

pytestmark = pytest.mark.slow


def test_every_plan_and_trace_hashes_as_recorded() -> None:
    golden = json.loads(GOLDEN.read_text())
    now = compute()
    assert sorted(now) == sorted(golden), "the instance set changed"
    changed = [key for key in golden if now[key] != golden[key]]
    assert not changed, f"{len(changed)} of {len(golden)} changed, e.g. {changed[:5]}"
