"""kerf_client: drive Kerf's real-time daemon ``kerfd`` from Python over iceoryx2 shared
memory, speaking protocol version 5 (docs/PROTOCOL.md).

    from kerf_client import Client, moves
    c = Client("default")
    print(c.status().status.position)
"""

from . import moves, protocol
from .client import (
    FINAL_FATES,
    OPERATOR_PAUSES,
    PAUSE_NAMES,
    Client,
    KerfError,
    ProgramResult,
    Reply,
    Setpoint,
    SetpointStream,
    Status,
    new_program_id,
    pause_name,
    wait_for_daemon,
)
from .moves import arc, arc_sweep, begin, end, event, line
from .protocol import *  # noqa: F401,F403 - the constants and messages
from .protocol import PROTOCOL_VERSION

__version__ = "0.1.0"

__all__ = [
    "Client",
    "KerfError",
    "ProgramResult",
    "Reply",
    "Setpoint",
    "SetpointStream",
    "Status",
    "FINAL_FATES",
    "OPERATOR_PAUSES",
    "PAUSE_NAMES",
    "PROTOCOL_VERSION",
    "new_program_id",
    "pause_name",
    "wait_for_daemon",
    "moves",
    "protocol",
    "arc",
    "arc_sweep",
    "begin",
    "end",
    "event",
    "line",
]
