"""TMSTC* (paper 002): turn-minimising trees and a time-balanced split of their STC cycle.

tiling (minimum brick tiling, König) -> merge (greedy by turn cost) -> improve (our edge
swaps) -> division (MSTC*-style split balanced by eq. 8 time); placement gives start sets.
"""

from __future__ import annotations

from planner.tmstc.division import divide
from planner.tmstc.plan import tmstc_plan
from planner.tmstc.tree import tmstc_tree
from planner.tmstc.types import BrickTiling, Division, RobotRoute

__all__ = ["BrickTiling", "Division", "RobotRoute", "divide", "tmstc_plan", "tmstc_tree"]
