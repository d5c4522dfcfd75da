"""Robustness campaigns (``mstc chaos``): seeded fault schedules, their injection into a
running fleet, and verdicts from simhw's ground truth and the mission's recording."""
