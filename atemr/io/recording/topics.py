"""Every channel a recording (and the live Foxglove server) carries: one table, read by writers and readers.

Sensor data, geometry and maps use ROS 2 messages in CDR (so ``ros2 bag play`` and Foxglove take
the file as it is); the agent's records (`atemr.fsm.recording`: one topic per kind) and state, the robot's
health and events, and CAN frames use JSON with a JSON schema. A reader checks a channel's schema against this
table, so a file whose ``/scan`` is something else is refused with what it found, never misread.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from atemr.io.recording.ros2_types import full_name, schema_text


@dataclass(frozen=True)
class Topic:
    """A channel: its name, its schema (name, encoding, text) and its messages' encoding."""

    name: str
    schema_name: str
    schema_encoding: str  # "ros2msg" | "jsonschema"
    schema_data: bytes
    message_encoding: str  # "cdr" | "json"
    #: What it carries, for docs/recording.md#what-is-recorded and ``atemr trace show --topics``.
    about: str = ""

    @property
    def is_ros2(self) -> bool:
        return self.message_encoding == "cdr"


def ros2(name: str, short_type: str, about: str) -> Topic:
    return Topic(name, full_name(short_type), "ros2msg", schema_text(short_type).encode(), "cdr", about)


def _number() -> dict[str, Any]:
    return {"type": "number"}


def json_topic(name: str, title: str, properties: dict[str, Any], required: list[str], about: str) -> Topic:
    schema = {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": title, "type": "object",
              "properties": properties, "required": required}
    return Topic(name, title, "jsonschema", json.dumps(schema, sort_keys=True).encode(), "json", about)


_ANY: dict[str, Any] = {}
_STR = {"type": "string"}
_RECORD = {"k": _STR, "t": _number()}


def _agent(kind: str, name: str, title: str, fields: dict[str, Any], about: str) -> Topic:
    return json_topic(name, f"atemr.agent.{title}", {**_RECORD, "k": {"const": kind}, **fields}, ["k", "t"], about)


_AGENT = [
    _agent("head", "/agent/head", "Head", {"v": {"type": "integer"}, "agent": _STR, "meta": {"type": "object"},
                                            "machine": {"type": "object"}},
           "first record of every file part: format version, agent name, run meta, the machine"),
    _agent("snap", "/agent/snapshot", "Snapshot", {"state": _STR, "mode": {"type": ["string", "null"]},
                                                   "transitions": {"type": "array"}, "blackboard": {"type": "object"}},
           "state, mode, last transitions and the whole blackboard when a part opens"),
    _agent("tr", "/agent/transitions", "Transition",
           {"trigger": _STR, "source": {"type": ["string", "null"]}, "dest": {"type": ["string", "null"]},
            "accepted": {"type": "boolean"}, "reason": {"type": ["string", "null"]}, "origin": _ANY,
            "decision": _ANY, "decided_by": _ANY}, "every transition attempt, with its reason and origin"),
    _agent("tree", "/agent/trees", "Tree", {"slot": _STR, "id": {"type": "integer"},
                                            "nodes": {"type": ["array", "null"]}},
           "a tree was built: its nodes in pre-order"),
    _agent("st", "/agent/node_status", "NodeStatus", {"id": {"type": "integer"}, "n": {"type": "array"}},
           "node status changes after a tick: [index, status, ticks, why]"),
    _agent("tk", "/agent/node_ticks", "NodeTicks", {"id": {"type": "integer"}, "n": {"type": "array"}},
           "tick counts that changed, once a second"),
    _agent("bb", "/agent/blackboard", "BlackboardWrite", {"key": _STR, "value": _ANY, "by": _ANY,
                                                          "unset": {"type": "boolean"}},
           "a blackboard key changed value, and who wrote it"),
    _agent("pose", "/agent/pose", "Pose", {"x": _number(), "y": _number(), "yaw": _number()},
           "the pose the agent sees, at trace.pose_hz (for the replay's map)"),
]
#: The agent recorder's record kinds (`atemr.fsm.recording`) and their topics.
AGENT_TOPICS: dict[str, Topic] = {t.name.removeprefix("/agent/"): t for t in _AGENT}
#: Record kind → topic name, and back.
KIND_TOPIC = {str(json.loads(t.schema_data)["properties"]["k"]["const"]): t.name for t in _AGENT}
TOPIC_KIND = {name: kind for kind, name in KIND_TOPIC.items()}

SCAN = ros2("/scan", "sensor_msgs/LaserScan", "every lidar revolution, in the laser frame")
IMU = ros2("/imu", "sensor_msgs/Imu", "every IMU sample (yaw rate, accelerations)")
WHEEL_ODOM = ros2("/wheel_odom", "geometry_msgs/TwistStamped",
                  "every wheel sample's measured twist, as localization receives it (50 Hz)")
ODOM = ros2("/odom", "nav_msgs/Odometry", "the fused odometry (wheels, IMU, scan matching) in odom")
POSE = ros2("/pose", "geometry_msgs/PoseWithCovarianceStamped", "the localized pose in map, while localized")
TF = ros2("/tf", "tf2_msgs/TFMessage", "map -> odom (while localized) and odom -> base_link")
TF_STATIC = ros2("/tf_static", "tf2_msgs/TFMessage", "base_link -> laser / imu_link / camera (every part)")
MAP = ros2("/map", "nav_msgs/OccupancyGrid", "the active map when it changes (and at every part's start)")
PLAN = ros2("/plan", "nav_msgs/Path", "the navigator's global path when it changes")
CAMERA = ros2("/camera/image/compressed", "sensor_msgs/CompressedImage", "camera frames as JPEG at trace.camera_hz")
DEPTH = ros2("/camera/depth/image_rect_raw", "sensor_msgs/Image",
             "depth frames (16UC1, millimetres, 0: no data) at trace.depth_hz, in camera_depth_optical_frame")
DEPTH_INFO = ros2("/camera/depth/camera_info", "sensor_msgs/CameraInfo",
                  "the depth camera's intrinsics, with each frame")
GROUND_TRUTH = ros2("/sim/ground_truth", "nav_msgs/Odometry", "the simulator's true pose (simulation only)")
HEALTH = json_topic("/health", "atemr.Health", {"t": _number(), "components": {
    "type": "object", "additionalProperties": {"type": "object", "properties": {"ok": {"type": "boolean"},
                                                                                "reason": _STR}}}},
    ["t", "components"], "every component's health, once a second")
GYRO_BIAS = json_topic("/odom/gyro_bias", "atemr.GyroBias", {"t": _number(), "bias_radps": _number(),
                                                             "standing": {"type": "boolean"}},
                       ["t", "bias_radps", "standing"],
                       "the gyro's bias as the odometry has learned it (while the wheels stand), once a second")
_FRAME = {"type": "object", "properties": {"id": {"type": "integer"}, "data": _STR, "extended": {"type": "boolean"},
                                          "remote": {"type": "boolean"}}, "required": ["id", "data"]}
CAN = json_topic("/can/frames", "atemr.CanFrames", {"t": _number(), "frames": {"type": "array", "items": _FRAME}},
                 ["t", "frames"], "every frame on the robot's CAN bus since the last message (data in hex), 20 Hz")
EVENTS = json_topic("/events", "atemr.Event", {"t": _number(), "kind": _STR, "text": _STR}, ["t", "kind", "text"],
                    "what the operator is told: faults, refusals, map changes, collisions")
MAPPING = json_topic("/mapping", "atemr.MappingSession", {"t": _number(), "active": {"type": "boolean"},
                                                         "collecting": {"type": "boolean"}},
                     ["t", "active", "collecting"], "a mapping session began, paused or ended (replay --slam)")
AGENT_STATE = json_topic("/agent/state", "atemr.agent.State", {"t": _number(), "state": _STR,
                                                              "mode": {"type": ["string", "null"]}},
                         ["t", "state"], "the agent's state and mode, when they change")

ROS2_TOPICS = (SCAN, IMU, WHEEL_ODOM, ODOM, POSE, TF, TF_STATIC, MAP, PLAN, CAMERA, DEPTH, DEPTH_INFO, GROUND_TRUTH)
TOPICS: dict[str, Topic] = {t.name: t for t in (*ROS2_TOPICS, CAN, HEALTH, GYRO_BIAS, EVENTS, MAPPING, AGENT_STATE,
                                                 *_AGENT)}


def topic(name: str) -> Topic:
    """The topic named ``name`` (`KeyError` for a name not in the table: a programming error)."""
    return TOPICS[name]


__all__ = ["AGENT_STATE", "AGENT_TOPICS", "CAMERA", "CAN", "DEPTH", "DEPTH_INFO", "EVENTS", "GROUND_TRUTH", "HEALTH",
           "IMU", "KIND_TOPIC", "MAP", "MAPPING", "ODOM", "PLAN", "POSE", "ROS2_TOPICS", "SCAN", "TF", "TF_STATIC",
           "TOPICS", "TOPIC_KIND", "WHEEL_ODOM", "Topic", "topic"]
