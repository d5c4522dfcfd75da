"""ORMSTC, the on-line robust multi-robot STC of Hazon, Mieli & Kaminka, as a sans-I/O machine."""

from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import InstantAnswers, MachineConfig, Priority, SenseMode
from planner.ormstc.walk import initial_arrival

__all__ = ["InstantAnswers", "MachineConfig", "OrmstcMachine", "Priority", "SenseMode",
           "initial_arrival"]
