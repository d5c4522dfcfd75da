"""The robot process, ``mstc agent``: agent.core plus one subpackage per algorithm family."""
