"""Sample tree environments for connected tree coverage (``*.tree`` files)."""
