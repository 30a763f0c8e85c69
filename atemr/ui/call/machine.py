"""The call's signalling state machine: who rings whom, who answered, who hung up, where an offer goes.

Pure: it knows Socket.IO session ids as strings and answers each input with the messages to send
(`Send`), so every rule is tested without a server or a browser. One call at a time per robot:

    idle --ring--> ringing --answer--> active --hang_up/left--> idle
                   ringing --decline/hang_up/left--> idle

The operator rings every connected screen (the tablet may have reloaded, or two tabs are open); the first
screen to answer takes the call and the others are told it was answered elsewhere. With auto-answer the
first screen answers at once. The operator's page makes the WebRTC offer once the call is active; the
machine only relays offers, answers and ICE candidates between the two parties of an active call.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

Phase = Literal["idle", "ringing", "active"]
STATE_EVENT = "call_state"
SIGNAL_EVENT = "call_signal"


@dataclass(frozen=True)
class Send:
    """One message to one Socket.IO session."""

    to: str
    event: str
    data: dict[str, Any]


@dataclass(frozen=True)
class Outcome:
    """The answer to one input: accepted or refused with the reason the page shows, and what to send."""

    ok: bool
    reason: str = ""
    sends: tuple[Send, ...] = ()

    @classmethod
    def refused(cls, reason: str) -> Outcome:
        return cls(False, reason)


@dataclass
class CallMachine:
    """The robot's one call. ``operator`` and ``screen`` are session ids; ``caller`` the operator's name."""

    phase: Phase = "idle"
    operator: str | None = None
    caller: str = ""
    screen: str | None = None
    rung: tuple[str, ...] = field(default_factory=tuple)

    def _state(self, to: str, phase: Phase, reason: str = "", role: str = "") -> Send:
        return Send(to, STATE_EVENT, {"state": phase, "caller": self.caller, "role": role, "reason": reason})

    def _end(self, sends: list[Send]) -> Outcome:
        self.phase, self.operator, self.caller, self.screen, self.rung = "idle", None, "", None, ()
        return Outcome(True, "", tuple(sends))

    def ring(self, operator: str, caller: str, screens: Sequence[str], *, auto_answer: bool = False) -> Outcome:
        """``caller`` (session ``operator``) calls the robot's ``screens``."""
        if self.phase != "idle":
            busy = "is ringing" if self.phase == "ringing" else "is in a call"
            who = "you" if operator == self.operator else self.caller
            return Outcome.refused(f"the robot {busy} with {who}: one call at a time")
        if not screens:
            return Outcome.refused("the robot's screen is not connected (is the tablet on, with its token?)")
        self.operator, self.caller, self.rung = operator, caller, tuple(screens)
        if auto_answer:
            self.phase = "ringing"
            return self.answer(screens[0])
        self.phase = "ringing"
        sends = [self._state(operator, "ringing", role="caller")]
        sends += [self._state(s, "ringing", role="callee") for s in screens]
        return Outcome(True, "", tuple(sends))

    def answer(self, screen: str) -> Outcome:
        """The screen ``screen`` answers: the call is active between it and the operator."""
        if self.phase != "ringing" or screen not in self.rung or self.operator is None:
            return Outcome.refused("there is no call ringing on this screen")
        self.phase, self.screen = "active", screen
        sends = [self._state(self.operator, "active", role="caller"), self._state(screen, "active", role="callee")]
        sends += [self._state(s, "idle", "answered on another screen") for s in self.rung if s != screen]
        return Outcome(True, "", tuple(sends))

    def decline(self, screen: str) -> Outcome:
        if self.phase != "ringing" or screen not in self.rung or self.operator is None:
            return Outcome.refused("there is no call ringing on this screen")
        sends = [self._state(self.operator, "idle", "the robot's screen declined the call")]
        sends += [self._state(s, "idle", "you declined the call") for s in self.rung]
        return self._end(sends)

    def hang_up(self, sid: str) -> Outcome:
        """``sid`` (the operator or the screen in the call) ends it, for both sides."""
        if self.phase == "idle" or sid not in self._parties():
            return Outcome.refused("there is no call to end")
        return self._end(self._goodbyes(sid, "hung up"))

    def left(self, sid: str) -> Outcome:
        """``sid`` disconnected (page closed, network gone): the call ends if it was a party."""
        if self.phase == "idle" or sid not in self._parties():
            return Outcome(True)
        if self.phase == "ringing" and sid != self.operator:
            self.rung = tuple(s for s in self.rung if s != sid)
            if self.rung:
                return Outcome(True)
        return self._end(self._goodbyes(sid, "left"))

    def relay(self, sid: str, data: dict[str, Any]) -> Outcome:
        """An offer, answer or ICE candidate from one party of the active call, sent to the other."""
        if self.phase != "active" or sid not in (self.operator, self.screen):
            return Outcome.refused("there is no active call to signal to")
        peer = self.screen if sid == self.operator else self.operator
        assert peer is not None
        return Outcome(True, "", (Send(peer, SIGNAL_EVENT, data),))

    def _parties(self) -> tuple[str, ...]:
        if self.operator is None:
            return ()
        return (self.operator, self.screen) if self.phase == "active" and self.screen else (self.operator, *self.rung)

    def _goodbyes(self, sid: str, how: str) -> list[Send]:
        assert self.operator is not None
        if sid == self.operator:
            others = [self.screen] if self.phase == "active" and self.screen else list(self.rung)
            return [self._state(self.operator, "idle", f"you {how}" if how == "hung up" else "you left"),
                    *(self._state(s, "idle", f"the caller {how}") for s in others)]
        return [self._state(sid, "idle", f"you {how}"),
                self._state(self.operator, "idle", f"the robot's screen {how}")]
