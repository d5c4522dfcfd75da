"""What every agent process shares, whatever its family: configuration, life cycle, announcer,
gather, hardware link, errors (docs/agent.md, "Module map")."""
