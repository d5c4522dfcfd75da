"""Offline MSTC (paper 003) as one family: the plan (STC cycle -> allocation -> walks), the
robot's takeover state machine, and its lockstep replay, side by side."""
