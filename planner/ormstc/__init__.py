"""ORMSTC, the on-line robust multi-robot STC of Hazon, Mieli & Kaminka, as a sans-I/O machine."""

from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import MachineConfig, Priority, SenseMode
from planner.ormstc.walk import initial_arrival

__all__ = ["MachineConfig", "OrmstcMachine", "Priority", "SenseMode", "initial_arrival"]
