"""Watching a fleet from the wire alone: the fleet model, its views, recordings and reports.

Nothing here imports agent/ or simhw/: the monitor knows the mission only through bus/
codecs, exactly what any other Zenoh subscriber could see.
"""
