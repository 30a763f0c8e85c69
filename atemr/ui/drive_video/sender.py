"""`DriveVideo`: the robot's side of the drive camera over WebRTC, one peer connection per Control page.

A page sends an offer for one receive-only video track (all its ICE candidates in it: the page waits for
its gathering first, so no candidates trickle); `answer` builds an aiortc peer connection on the
`EventLoopThread`, puts a `CameraTrack` on it and returns the answer, whose candidates aiortc gathers
before it answers. The web request that asked waits for that, up to `NEGOTIATE_TIMEOUT_S`, on its own
thread; the robot's control loop never waits on any of it (the track only reads the newest frame).

Each socket has at most one connection (a new offer replaces the old one); at most
``ui.drive_video_max_peers`` run at once, since each costs an encoder on the robot. A connection that fails
or closes is dropped; a socket that goes closes its own (`close`). Whatever cannot be had (``ui.drive_video:
mjpeg``, aiortc not installed, no camera, every peer taken, a negotiation that fails) is refused with the
reason, and the page falls back to MJPEG and says so.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures import wait as wait_futures
from dataclasses import dataclass, field
from typing import Any

from atemr.errors import AtemrError
from atemr.ui.drive_video.loop import EventLoopThread
from atemr.ui.drive_video.pacing import Frames

log = logging.getLogger(__name__)

#: Seconds a page's offer may take to be answered (aiortc gathers its candidates first).
NEGOTIATE_TIMEOUT_S = 15.0
#: Seconds `shutdown` gives the connections to close.
CLOSE_TIMEOUT_S = 3.0
#: What the page shows when the robot's Python has no aiortc.
NO_AIORTC = "aiortc is not installed on the robot (pip install 'atemr[webrtc]')"


@dataclass(frozen=True)
class Availability:
    """Whether a page should try WebRTC, why not when it should not, and the ICE servers to use."""

    webrtc: bool
    reason: str = ""
    ice_servers: list[dict[str, Any]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"webrtc": self.webrtc, "reason": self.reason, "ice_servers": self.ice_servers}


def aiortc_missing() -> str | None:
    """Why aiortc cannot be imported (None: it can). Imported on first use only: it is large and optional."""
    try:
        importlib.import_module("aiortc")
        importlib.import_module("atemr.ui.drive_video.track")
    except ImportError as exc:
        log.info("drive video over WebRTC is off: %s", exc)
        return NO_AIORTC
    return None


class DriveVideo:
    """The robot's WebRTC drive-video connections (thread-safe; see the module docstring)."""

    def __init__(self, frames: Frames | None, *, enabled: bool, max_peers: int,
                 ice_servers: Callable[[], list[dict[str, Any]]]) -> None:
        """``ice_servers`` is asked at each page's question and each offer: TURN credentials made from a shared
        secret expire, so they are made when used (`atemr.ui.call.events.ice_servers`)."""
        self._frames = frames
        self.enabled = enabled
        self.max_peers = max_peers
        self.ice_servers = ice_servers
        self._lock = threading.Lock()
        self._missing: str | None = None
        self._checked = False
        self._peers: dict[str, Any] = {}  # sid → RTCPeerConnection
        self._closing: set[Future[None]] = set()  # closes under way (`close`), which `shutdown` lets finish
        self._loop = EventLoopThread("atemr-drive-video")

    # -- what a page may try ---------------------------------------------------------------------------
    def availability(self) -> Availability:
        """Whether WebRTC may be tried (the peers' limit is checked at the offer: it changes)."""
        if not self.enabled:
            return Availability(False, "the robot is set to send its camera as MJPEG (ui.drive_video)")
        if self._frames is None:
            return Availability(False, "no robot is connected: no camera")
        with self._lock:
            if not self._checked:
                self._missing, self._checked = aiortc_missing(), True
            missing = self._missing
        if missing:
            return Availability(False, missing)
        return Availability(True, "", self.ice_servers())

    @property
    def peers(self) -> int:
        """Connections open now."""
        with self._lock:
            return len(self._peers)

    # -- the web threads ---------------------------------------------------------------------------------
    def answer(self, sid: str, offer: dict[str, str]) -> dict[str, str]:
        """The answer (``{type, sdp}``) to the page on socket ``sid`` offering ``offer``; `DriveVideoError`
        with the reason when WebRTC cannot be had."""
        why = self.availability()
        if not why.webrtc:
            raise DriveVideoError(why.reason)
        self.close(sid)  # a page offers again after a reconnect or CAM off and on: its old connection goes
        with self._lock:
            if len(self._peers) >= self.max_peers:
                raise DriveVideoError(f"the robot sends WebRTC video to {self.max_peers} page(s) at most "
                                        "(ui.drive_video_max_peers); this one gets MJPEG")
            self._peers[sid] = None  # the place is taken while negotiating
        future = self._loop.submit(self._negotiate(sid, offer))
        try:
            return future.result(timeout=NEGOTIATE_TIMEOUT_S)
        except FutureTimeout:
            future.cancel()
            self.close(sid)
            late = f"the robot did not answer the video offer within {NEGOTIATE_TIMEOUT_S:g} s"
            raise DriveVideoError(late) from None
        except Exception as exc:
            self.close(sid)
            if isinstance(exc, DriveVideoError):
                raise
            log.warning("drive video offer from %s failed: %s: %s", sid, type(exc).__name__, exc)
            raise DriveVideoError(f"the video offer could not be answered: {exc}") from None

    def close(self, sid: str) -> None:
        """Close the connection of socket ``sid`` (none: nothing happens); does not wait for it."""
        with self._lock:
            pc = self._peers.pop(sid, None)
        if pc is not None and self._loop.running:
            closing = self._loop.submit(pc.close())
            with self._lock:
                self._closing.add(closing)
            closing.add_done_callback(self._closed)

    def _closed(self, closing: Future[None]) -> None:
        with self._lock:
            self._closing.discard(closing)

    def shutdown(self) -> None:
        """Close every connection, let the closes under way finish, and stop the loop (idempotent).

        A close cut short by the loop's end leaves its sockets open: aioice's shared mDNS resolver (opened for a
        browser's ``.local`` candidates) among them. So a page that left just before the robot stopped has its
        close waited for too, up to `CLOSE_TIMEOUT_S` with the rest."""
        with self._lock:
            peers = [pc for pc in self._peers.values() if pc is not None]
            self._peers.clear()
            closing = list(self._closing)
        if self._loop.running and (peers or closing):
            if peers:
                closing.append(self._loop.submit(_close_all(peers)))
            _, late = wait_futures(closing, timeout=CLOSE_TIMEOUT_S)
            if late:  # the loop ends anyway, taking what is left with it
                log.warning("drive video: %d connection(s) did not close within %g s", len(late), CLOSE_TIMEOUT_S)
        self._loop.stop()

    # -- the loop's thread -------------------------------------------------------------------------------
    async def _negotiate(self, sid: str, offer: dict[str, str]) -> dict[str, str]:
        from aiortc import RTCConfiguration, RTCIceServer, RTCPeerConnection, RTCSessionDescription

        from atemr.ui.drive_video.track import CameraTrack

        assert self._frames is not None
        servers = [RTCIceServer(urls=s["urls"], username=s.get("username"), credential=s.get("credential"))
                   for s in self.ice_servers()]
        pc = RTCPeerConnection(RTCConfiguration(iceServers=servers or None))
        with self._lock:
            if sid not in self._peers:  # the socket went or offered again while this waited
                await pc.close()
                raise DriveVideoError("the page left before its video was answered")
            self._peers[sid] = pc

        @pc.on("connectionstatechange")
        async def changed() -> None:
            log.debug("drive video %s: %s", sid, pc.connectionState)
            if pc.connectionState in ("failed", "closed"):
                with self._lock:
                    if self._peers.get(sid) is pc:
                        del self._peers[sid]
                await pc.close()

        await pc.setRemoteDescription(RTCSessionDescription(sdp=offer["sdp"], type=offer["type"]))
        if not any(t.kind == "video" for t in pc.getTransceivers()):
            raise DriveVideoError("the offer asks for no video")
        pc.addTrack(CameraTrack(self._frames))
        await pc.setLocalDescription(await pc.createAnswer())
        local = pc.localDescription
        return {"type": local.type, "sdp": local.sdp}


async def _close_all(peers: list[Any]) -> None:
    await asyncio.gather(*(pc.close() for pc in peers), return_exceptions=True)


class DriveVideoError(AtemrError):
    """WebRTC drive video cannot be had for this page now; the message says why (the page shows it)."""
