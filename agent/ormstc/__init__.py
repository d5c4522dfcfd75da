"""The online family (ormstc): the ORMSTC machine driven with a sonar body, no map."""
