"""The CAN layer: the inter-core protocol codec (0x150–0x157), segmented transfer, the shipped DBC,
bus factory, supervisor, fault-injection bus and bus recording.

The protocol names are re-exported here so other parts import them from one place::

    from atemr.io.can import PrimaryStatus, decode

The values the messages carry (`StateCode`, `AgentBits`, `HardwareBits`, `PowerState`, `PowerRequest`) are
domain types: import them from `atemr.domain.status`.
"""

from atemr.io.can.protocol import (
    ID_NAMES,
    MESSAGE_TYPES,
    CanId,
    Heartbeat,
    IpAddress,
    IpRequest,
    IrFront,
    IrRear,
    Message,
    Power,
    PrimaryStatus,
    WifiPasswordSegment,
    WifiSsidSegment,
    decode,
    id_name,
    is_protocol_id,
)
from atemr.io.can.segmented import (
    PASSWORD,
    SSID,
    TEXT_FIELDS,
    SegmentedReceiver,
    SegmentedSender,
    TextField,
    encode_text,
    segment_text,
)

__all__ = [
    "ID_NAMES", "MESSAGE_TYPES", "PASSWORD", "SSID", "TEXT_FIELDS", "CanId", "Heartbeat",
    "IpAddress", "IpRequest", "IrFront", "IrRear", "Message", "Power", "PrimaryStatus",
    "SegmentedReceiver", "SegmentedSender", "TextField", "WifiPasswordSegment", "WifiSsidSegment",
    "decode", "encode_text", "id_name", "is_protocol_id", "segment_text",
]
