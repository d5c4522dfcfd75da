"""The router's authentication and access control for one mission, derived from the
``access`` column of the wire schema (bus.messages.schema): nothing here lists keys by hand.

Every authenticated role may subscribe to, query the liveliness of, and receive everything of
its mission; writing (put, serving a queryable and replying, querying, liveliness tokens) is
allowed exactly where the schema names the role. Where a role may put on a recoverable family,
it may also run that family's advanced publishers (bus.recovery: a cache queryable, a
detection token and heartbeats under each key's ``@adv`` chunk), and every role may query
those caches to recover what it missed. Everything else is denied, and so is every
key outside ``mstc/<mission>/`` (the admin space included). Zenoh's ACL only sees the
transport a message came in on, so it cannot tell what a robot says inside its own keys:
bus.bridge and bus.liveness check that.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from bus import keys
from bus.messages.schema import ALIVE, FAMILIES, Audience, KeyFamily
from bus.recovery import advanced_keys
from bus.security.credentials import Credentials
from bus.security.roles import ROUTER_COMMON_NAME, Role

# Zenoh's ACL message types
_READ_IN = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query")
_ALL = ("put", "delete", "declare_subscriber", "query", "reply", "declare_queryable",
        "liveliness_token", "declare_liveliness_subscriber", "liveliness_query")
_VERBS: dict[str, tuple[str, ...]] = {
    "put": ("put",),
    "serve": ("declare_queryable", "reply"),
    "ask": ("query",),
    "token": ("liveliness_token",),
    # an advanced publisher's own keys: heartbeats, its cache queryable, its detection token
    "advanced": ("put", "declare_queryable", "reply", "liveliness_token"),
    # its cache answers with the samples as they were put: on the family's own keys
    "cache": ("reply",),
}
# What a recovering subscriber does on the advanced keys besides reading: ask the caches.
_RECOVER_IN = (*_READ_IN, "query")


def _covers(audience: Audience, role: Role) -> bool:
    if audience in ("own", "robots"):
        return role.kind == "robot"
    return audience == "everyone" or audience == role.kind


def grants(role: Role, mission: str,
           families: Iterable[KeyFamily] = (*FAMILIES, ALIVE)) -> dict[str, list[str]]:
    """Verb -> key expressions ``role`` may use it on (verbs: put, serve, ask, token, and
    advanced and cache: the advanced publishers of the recoverable families it may put
    on)."""
    out: dict[str, list[str]] = {verb: [] for verb in _VERBS}
    for fam in families:
        for verb in ("put", "serve", "ask", "token"):
            audiences: tuple[Audience, ...] = getattr(fam.access, verb)
            for audience in audiences:
                if _covers(audience, role):
                    robot = role.robot if audience == "own" else None
                    key = keys.of_robot(fam.label, mission, robot)
                    if key not in out[verb]:
                        out[verb].append(key)
                    if verb == "put" and fam.cache > 0 and key not in out["cache"]:
                        out["cache"].append(key)
                        out["advanced"].append(advanced_keys(key))
    return {verb: found for verb, found in out.items() if found}


def access_control(mission: str, roles: Iterable[Role], *,
                   by_certificate: bool = False) -> dict[str, Any]:
    """Zenoh's ``access_control`` section. A role is its user name; with ``by_certificate``
    (mTLS) its TLS client certificate's common name must be the same name as well."""
    everything = keys.everything(mission)
    rules: list[dict[str, Any]] = [
        {"id": "read", "messages": list(_READ_IN), "flows": ["ingress"],
         "permission": "allow", "key_exprs": [everything]},
        {"id": "recover", "messages": list(_RECOVER_IN), "flows": ["ingress"],
         "permission": "allow", "key_exprs": [advanced_keys(everything)]},
        {"id": "receive", "messages": list(_ALL), "flows": ["egress"],
         "permission": "allow", "key_exprs": [everything, advanced_keys(everything)]},
    ]
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    names = []
    for role in roles:
        if role.kind == "router":
            continue  # its log-in grants nothing: routers go by their certificate (below)
        subject: dict[str, Any] = {"id": role.name, "usernames": [role.name]}
        if by_certificate:
            subject["cert_common_names"] = [role.name]
        subjects.append(subject)
        names.append(role.name)
        own_rules = []
        for verb, key_exprs in grants(role, mission).items():
            rule_id = f"{role.name}/{verb}"
            rules.append({"id": rule_id, "messages": list(_VERBS[verb]),
                          "flows": ["ingress"], "permission": "allow",
                          "key_exprs": key_exprs})
            own_rules.append(rule_id)
        if own_rules:
            policies.append({"id": role.name, "rules": own_rules, "subjects": [role.name]})
    policies.append({"id": "readers", "rules": ["read", "recover", "receive"],
                     "subjects": names})
    if by_certificate:
        # Routers of other hosts, both ways: the one that joined this router (its client
        # certificate) and the one this router joined (its server certificate; that side
        # never logs in here). A router forwards every role's traffic, each role checked by
        # the router it logged in to, so the link may carry all of the mission.
        subjects.append({"id": "routers", "cert_common_names": [ROUTER_COMMON_NAME]})
        rules.append({"id": "routers/forward", "messages": list(_ALL),
                      "flows": ["ingress"], "permission": "allow",
                      "key_exprs": [everything, advanced_keys(everything)]})
        policies.append({"id": "routers", "rules": ["routers/forward", "receive"],
                         "subjects": ["routers"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


def router_values(creds: Credentials, dictionary_file: Path, *,
                  by_certificate: bool = False) -> dict[str, Any]:
    """The router's Zenoh settings: log-ins checked against ``dictionary_file`` (written from
    ``creds``), and the access control of ``creds.mission`` for the roles listed there."""
    return {
        "transport/auth/usrpwd/dictionary_file": str(dictionary_file),
        "access_control": access_control(creds.mission, creds.roles,
                                         by_certificate=by_certificate),
    }
