"""The runtime's message protocol: the key space, the messages and their validation.

Each message is declared once, in :mod:`.messages` (its fields, their types and
constraints: :mod:`.schema`); :mod:`.codec` encodes and decodes them from that
declaration. Imports nothing from the rest of ``cekm_swarm`` but ``cekm_swarm.errors``,
so the world server (which must not import controller code) can use it.
"""

from .codec import decode, encode, peek, summary, to_plain, to_wire
from .drops import DropCounter, DropRecord
from .errors import (
                     KeySpaceError,
                     MessageArrayError,
                     MessageError,
                     MessageFieldError,
                     MessageFormatError,
                     MessageKindError,
                     MessageVersionError,
                     ProtocolError,
)
from .keys import (
                     DEFAULT_KEYS,
                     DEFAULT_RANGE_SENSORS,
                     DEFAULT_ROOT,
                     WORLD,
                     KeyKind,
                     KeySpace,
                     ParsedKey,
                     validate_module_name,
                     validate_robot_id,
                     validate_root,
                     validate_run_id,
)
from .messages import (
                     MESSAGE_TYPES,
                     MSGPACK_ENCODING,
                     SCHEMA_VERSION,
                     Clock,
                     Data,
                     MapVersion,
                     Message,
                     ObstacleField,
                     ObstacleState,
                     RobotState,
                     SenseOdometry,
                     SensePose,
                     SenseRange,
                     SenseTarget,
                     SenseTargets,
                     Share,
                     TargetField,
                     TargetState,
                     TrackingField,
                     Unchanged,
                     WheelCommand,
                     WorldState,
                     with_stamp,
)
from .schema import Angle, Count, Distance, Finite, Plain, Point, Pose, Vector, Weight
from .user import USER_TYPES, Nothing, ParamChange, UntypedData, UserMessage, expect_of, is_message_type, kind_of

__all__ = [
    "DropCounter", "DropRecord",
    "KeySpaceError", "MessageArrayError", "MessageError", "MessageFieldError", "MessageFormatError",
    "MessageKindError", "MessageVersionError", "ProtocolError",
    "DEFAULT_KEYS", "DEFAULT_RANGE_SENSORS", "DEFAULT_ROOT", "WORLD", "KeyKind", "KeySpace", "ParsedKey",
    "validate_module_name", "validate_robot_id", "validate_root", "validate_run_id",
    "MESSAGE_TYPES", "MSGPACK_ENCODING", "SCHEMA_VERSION", "Clock", "Data", "MapVersion", "Message", "ObstacleField",
    "ObstacleState", "RobotState", "SenseOdometry", "SensePose", "SenseRange", "SenseTarget", "SenseTargets", "Share",
    "TargetField",
    "TargetState", "TrackingField", "Unchanged", "WheelCommand", "WorldState", "with_stamp",
    "decode", "encode", "peek", "summary", "to_plain", "to_wire",
    "Angle", "Count", "Distance", "Finite", "Plain", "Point", "Pose", "Vector", "Weight",
    "USER_TYPES", "Nothing", "ParamChange", "UntypedData", "UserMessage", "expect_of", "is_message_type", "kind_of",
]
