"""Kept only so that importers of the old path need no edit; the kinds live in
bus/messages/tree.py (import them from ``bus.messages``)."""

from bus.messages.tree import RadioStats, TreeReport

__all__ = ["RadioStats", "TreeReport"]
