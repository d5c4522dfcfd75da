"""Wire messages: frozen dataclasses, one per kind, filed by subject.

schema     the table: every kind's class, key families, QoS class and wire generation
base       the plain aliases (Pose, SubCell, Cell, SummaryValue)
lifecycle  Heartbeat, RobotStatus (Hello), RobotEvent, DeathNotice, MissionStatus
progress   Progress, LookStep, AgentState (with pack_covered / unpack_covered)
hardware   HwCommand / HwReply, AdminCommand / AdminReply (the simulated hardware's API)
world      the simulator's ground truth: GroundTruthPose, CoverEvent, BumpEvent, WorldState
ormstc     the seven ORMSTC kinds (ORMSTC_MESSAGES, OrmstcWire), SonarRays (rays for peers)
tree       TreeReport, RadioStats (connected tree coverage in the fleet)

Every public name is re-exported here: import messages from ``bus.messages``.
"""

from bus.messages.base import Cell, Pose, SubCell, SummaryValue
from bus.messages.hardware import (
    AdminAction,
    AdminCommand,
    AdminReply,
    HwAction,
    HwCommand,
    HwReply,
    HwStatus,
    Sensor,
)
from bus.messages.lifecycle import (
    DeathNotice,
    DeathReason,
    EventKind,
    Heartbeat,
    Hello,
    MissionState,
    MissionStatus,
    RobotEvent,
    RobotStateName,
    RobotStatus,
)
from bus.messages.ormstc import (
    ORMSTC_MESSAGES,
    OrmstcClaim,
    OrmstcCompletion,
    OrmstcConnection,
    OrmstcDeadRobot,
    OrmstcRetraction,
    OrmstcStart,
    OrmstcTreeEdge,
    OrmstcWire,
    OrmstcWithdrawal,
    SonarRays,
)
from bus.messages.plan import PlanShare, join_moves, pack_moves, split_moves, unpack_moves
from bus.messages.progress import (
    AgentState,
    LookStep,
    Progress,
    ReplanReport,
    ReplanShare,
    pack_covered,
    pack_routes,
    unpack_covered,
    unpack_routes,
)
from bus.messages.schema import (
    KIND_SINCE,
    MESSAGE_TYPES,
    RECORD_TYPES,
    SCHEMA_VERSION,
    version_problem,
)
from bus.messages.tree import RadioStats, TreeReport
from bus.messages.world import (
    NO_ROBOT,
    BumpEvent,
    CoverEvent,
    GroundTruthPose,
    RobotArray,
    RobotTruth,
    WorldState,
    make_world_state,
    world_crossed,
    world_first,
    world_free,
    world_visits,
)

__all__ = [
    "KIND_SINCE", "MESSAGE_TYPES", "NO_ROBOT", "ORMSTC_MESSAGES", "RECORD_TYPES", "SCHEMA_VERSION",
    "AdminAction", "AdminCommand", "AdminReply", "AgentState", "BumpEvent", "Cell", "CoverEvent",
    "DeathNotice", "DeathReason", "EventKind", "GroundTruthPose", "Heartbeat", "Hello", "HwAction",
    "HwCommand", "HwReply", "HwStatus", "LookStep", "MissionState", "MissionStatus", "OrmstcClaim",
    "OrmstcCompletion", "OrmstcConnection", "OrmstcDeadRobot", "OrmstcRetraction", "OrmstcStart",
    "OrmstcTreeEdge", "OrmstcWire", "OrmstcWithdrawal", "PlanShare", "Pose", "Progress",
    "RadioStats", "ReplanReport", "ReplanShare", "RobotArray", "RobotEvent", "RobotStateName",
    "RobotStatus", "RobotTruth", "Sensor", "SonarRays", "SubCell", "SummaryValue", "TreeReport",
    "WorldState", "join_moves", "make_world_state", "pack_covered", "pack_moves", "pack_routes",
    "split_moves", "unpack_covered", "unpack_moves", "unpack_routes", "version_problem",
    "world_crossed", "world_first", "world_free", "world_visits",
]
