"""The Zenoh wire of mstc-swarm (schema and rules: docs/protocol.md).

messages  frozen message dataclasses by subject (bus/messages/) and the wire schema
          (bus/messages/schema.py: per kind its class, key families, QoS class, generation)
keys      every key expression, built and parsed from the schema's key families
codec     strict, versioned msgpack encode/decode of the schema's kinds
drops     DropCounter for malformed and overflowing messages
qos       the Zenoh priority / congestion control of each QoS class of the schema
config    command-line options -> ConnectionSettings -> zenoh.Config; open_session
bridge    Bus: asyncio pub/sub, queries, queryables and liveliness over one session
detector  FailureDetector: who is dead, from heartbeats, tokens and notices (sans-I/O)
liveness  HeartbeatPublisher, LivelinessService: the token, heartbeats and the detector's I/O
announce  Announcer: periodically re-published, queryable state
handoff   a thread per declaration hands its items to the loop: Zenoh never waits for Python
inbox     thread-to-loop hand-off buffers and their policies (LatestWins, BoundedFifo)
router    the embedded router (``mstc router``) and a helper to start it as a process
"""
