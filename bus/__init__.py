"""The Zenoh wire of mstc-swarm (schema and rules: docs/protocol.md).

keys      every key expression (no other module builds key strings)
messages  frozen message dataclasses by subject (bus/messages/), registered by kind
codec     strict, versioned msgpack encode/decode
drops     DropCounter for malformed and overflowing messages
qos       priority / congestion control per message kind
config    command-line options -> ConnectionSettings -> zenoh.Config; open_session
bridge    Bus: asyncio pub/sub, queries, queryables and liveliness over one session
liveness  FailureDetector (sans-I/O), HeartbeatPublisher, LivelinessService
announce  Announcer: periodically re-published, queryable state
inbox     thread-to-loop hand-off buffers and their policies (LatestWins, BoundedFifo)
router    the embedded router (``mstc router``) and a helper to start it as a process
"""
