"""Pure experiment generators: seeded instances and per-trial measurements for the papers."""
