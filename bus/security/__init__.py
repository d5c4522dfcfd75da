"""Who may do what on the bus of one mission (docs/security.md).

roles        the roles (robot i, simhw, operator, observer, router) and their user names
credentials  the per-mission credentials file (JSON, mode 0600) and where tools find it
acl          the router's authentication and access-control configuration, derived from
             the access column of the wire schema (bus.messages.schema)
"""
